-- expect: error __gc metamethod stopped: callback exceeded its instruction budget
-- issue 21 item 2: a __gc that loops, run by lua_close at exit (before: hang at exit).
setmetatable({}, {__gc = function() while true do end end})
print("script done")
