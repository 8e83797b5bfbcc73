-- expect: error instruction budget
-- issue 21 item 2: Lua's own coroutine.resume, fished out before the callback (an upvalue of
-- the wrapper, or a frame seen by debug.getinfo), runs a hook-less coroutine (before: hang).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
local raw = select(3, pcall(debug.getupvalue, coroutine.resume, 1)) -- ok, name, value
if type(raw) ~= "function" then raw = coroutine.resume end -- refused: cdvr's own, which passes the budget on
local loop = coroutine.create(function() while true do end end)
c.play(function() raw(loop); return "S4T3" end)
