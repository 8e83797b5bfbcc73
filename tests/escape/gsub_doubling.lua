-- expect: error callback exceeded its instruction budget
-- issue 21 item 2: a gsub that doubles its string in a loop inside a policy (its matching steps
-- count; before: ran out of memory).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.play(function()
  local s = "xxxxxxxx"
  for _ = 1, 40 do s = s:gsub(".", "%0%0") end
  return "S4T3"
end)
