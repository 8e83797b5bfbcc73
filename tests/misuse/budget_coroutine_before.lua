-- expect: error instruction budget
-- issue 11 item 4: a runaway coroutine created before the callback (no hook on it; before: hang).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local co = coroutine.create(function() while true do end end)
local p = c.player(st, {callback_limit = 100000, policy = function()
  coroutine.resume(co)
  return 'S4T3'
end})
p:run{frames = 3}
