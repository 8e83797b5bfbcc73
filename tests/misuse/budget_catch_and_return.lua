-- expect: error instruction budget
-- issue 11 item 4: a callback that catches the budget error once and returns normally still fails.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local p = c.player(st, {callback_limit = 100000, policy = function()
  pcall(function() while true do end end)
  return 'S4T3'
end})
p:run{frames = 3}
