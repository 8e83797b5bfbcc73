-- expect: error instruction budget
-- issue 11 item 4: a coroutine.wrap function made before the callback runs away in it.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local spin = coroutine.wrap(function() while true do end end)
local p = c.player(st, {callback_limit = 100000, camera = function() spin() return c.camera end})
p:run{frames = 3}
