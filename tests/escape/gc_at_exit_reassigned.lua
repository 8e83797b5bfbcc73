-- expect: error __gc metamethod stopped: callback exceeded its instruction budget
-- issue 21 item 2: a metatable whose __gc is replaced by a loop after setmetatable, and one set
-- through debug.setmetatable; both run at exit (before: hang at exit).
local mt = {__gc = true}
local keep = setmetatable({}, mt)
mt.__gc = function() while true do end end
debug.setmetatable(function() end, nil) -- harmless use of the guarded function
local t = {}
debug.setmetatable(t, {__gc = function() local x = 0 while true do x = x + 1 end end})
print(getmetatable(keep) == mt)
