-- expect: error instruction budget
-- issue 11 item 4: coroutine.close running a to-be-closed variable that loops.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local co = coroutine.create(function()
  local x <close> = setmetatable({}, {__close = function() while true do end end})
  coroutine.yield()
end)
coroutine.resume(co)
local p = c.player(st, {callback_limit = 100000, policy = function()
  coroutine.close(co)
  return 'S4T3'
end})
p:run{frames = 3}
