-- expect: error debug.getregistry is not available in a callback
-- issue 21 item 2: a policy that reaches the registry (where the budget used to live), then loops.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
c.play(function()
  local reg = debug.getregistry()
  for k in pairs(reg) do if type(k) == "string" and k:find("budget") then reg[k] = nil end end
  while true do end
end)
