-- expect: ok finalizers ran: all
-- issue 21 item 2: ordinary finalizers still run (guarded), in and outside callbacks, and
-- getmetatable still returns the metatable given.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
local ran, made = 0, 0
local mt = {__gc = function(o) ran = ran + o.n end}
local function make() made = made + 1; return setmetatable({n = 1}, mt) end
assert(getmetatable(make()) == mt)
collectgarbage(); collectgarbage()
assert(ran == 1, "finalizer outside callbacks did not run")
c.play(function() make(); collectgarbage(); return "S4T3" end)
collectgarbage(); collectgarbage()
assert(made > 1 and ran == made, string.format("%d of %d finalizers ran", ran, made))
print("finalizers ran: all")
