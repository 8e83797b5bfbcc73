-- expect: error instruction budget
-- issue 21 item 2: a __gc that loops, collected inside a policy (Lua runs __gc with hooks off;
-- before: hang).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.play(function()
  setmetatable({}, {__gc = function() while true do end end})
  collectgarbage()
  return "S4T3"
end)
