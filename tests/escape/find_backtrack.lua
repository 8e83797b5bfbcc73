-- expect: error instruction budget
-- issue 21 item 2: a backtracking string.find in a policy (exponential, all in C; before: hang).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.play(function()
  local s = string.rep("a", 40)
  s:find(string.rep(".-", 20) .. "b")
  return "S4T3"
end)
