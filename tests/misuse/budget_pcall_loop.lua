-- expect: error instruction budget
-- issue 11 item 4: a runaway loop wrapped in pcall swallows each budget error (before: hang).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local p = c.player(st, {callback_limit = 100000, policy = function()
  while true do pcall(function() while true do end end) end
end})
p:run{frames = 3}
