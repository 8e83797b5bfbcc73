-- expect: error instruction budget
-- issue 11 item 4: pcall-swallowed loop inside a coroutine created before the callback.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local co = coroutine.create(function() while true do pcall(function() while true do end end) end end)
local p = c.player(st, {callback_limit = 100000, camera = function()
  while true do coroutine.resume(co) end
end})
p:run{frames = 3}
