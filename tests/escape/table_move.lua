-- expect: error instruction budget
-- issue 21 item 2: table.move of 1e15 elements loops in C inside a policy (before: hang).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.play(function() table.move({}, 1, 1e15, 1, {}); return "S4T3" end)
