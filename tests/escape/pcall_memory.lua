-- expect: ok memory bounded
-- issue 21 item 2: a policy that catches its memory error keeps within the budget (the state
-- never grows past it) and later callbacks run normally.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
local caught = 0
c.play(function()
  local ok = pcall(string.rep, "x", 1 << 30)
  if not ok then caught = caught + 1 end
  assert(collectgarbage("count") < 300 * 1024)
  return "S4T3"
end)
assert(caught > 0)
print("memory bounded")
