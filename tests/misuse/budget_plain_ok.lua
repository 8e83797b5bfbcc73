-- expect: ok budget resets per callback
-- issue 11 item 4: the budget is per call: many callbacks each below it play through, and
-- coroutines still work normally inside and outside callbacks.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/misuse/?.lua;" .. package.path
local c = require "common"
local st = c.store()
local gen = coroutine.wrap(function() for i = 1, math.huge do coroutine.yield(i) end end)
local p = c.player(st, {callback_limit = 100000, loop = true, camera = function(frame)
  for i = 1, 5000 do end
  assert(gen() == frame)
  local ok, v = coroutine.resume(coroutine.create(function(a) return a * 2 end), frame)
  assert(ok and v == 2 * frame)
  return c.camera
end})
local r = p:run{frames = 12}
assert(#r.frames == 12)
assert(gen() == 13)
local ok, msg = pcall(coroutine.wrap(function() error('boom') end))
assert(not ok and msg:find('boom'))
-- xpcall keeps Lua's behaviour: the handler's result, extra arguments, yields across it
local ok2, handled = xpcall(error, function(m) return 'handled: ' .. m end, 'x', 0)
assert(not ok2 and handled == 'handled: x', handled)
assert(select('#', xpcall(function(...) return ... end, print, 1, nil, 3)) == 4)
local co = coroutine.wrap(function() return xpcall(function() return coroutine.yield(1) + 1 end, print) end)
assert(co() == 1)
local ok3, two = co(1)
assert(ok3 and two == 2)
print('budget resets per callback')
