-- expect: ok collected
-- issue 11 item 1: a player and its closed store collected together (any finalizer order).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
for i = 1, 3 do
  local st = c.store('g' .. i)
  local p = c.player(st)
  if i == 2 then st:close() end
  if i == 3 then p:run{frames = 1} end
end
collectgarbage() collectgarbage()
print('collected')
