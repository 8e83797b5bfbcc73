-- expect: error instruction budget
-- issue 11 item 4: xpcall in a loop, with a message handler that loops too.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local p = c.player(st, {callback_limit = 100000, policy = function()
  while true do xpcall(function() while true do end end, function(m) while true do end end) end
end})
p:run{frames = 3}
