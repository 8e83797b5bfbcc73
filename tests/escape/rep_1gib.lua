-- expect: error callback exceeded its memory budget (callback_memory = 256 MB)
-- issue 21 item 2: string.rep of 1 GiB in a policy (before: 1 GiB resident per call).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.play(function() local s = string.rep("x", 1 << 30); return "S4T3" end)
