-- expect: error debug.sethook is not available in a callback
-- issue 21 item 2: a policy that removes the budget hook, then loops (before: hang).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.play(function() debug.sethook(); while true do end end)
