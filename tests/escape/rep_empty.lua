-- expect: ok rep done
-- issue 21 item 2: string.rep("", 1e15) loops 1e15 times in Lua's own (before: hang).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
assert(string.rep("", 1e15) == "" and string.rep("ab", 3, ",") == "ab,ab,ab")
c.play(function() assert(string.rep("", 1e15) == ""); return "S4T3" end)
print("rep done")
