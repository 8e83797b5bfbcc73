-- expect: error __gc metamethod stopped: callback exceeded its memory budget
-- issue 21 item 2: a __gc that allocates without bound at exit (before: out of memory).
setmetatable({}, {__gc = function() local s = "x" while true do s = s .. s end end})
