-- expect: error instruction budget
-- issue 21 item 2: Lua's own xpcall reached through debug.getinfo (a frame below the wrapper),
-- whose message handler runs with hooks off; the handler loops (before: hang).
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
local raw = xpcall
xpcall(function()
  for level = 2, 4 do
    local info = debug.getinfo(level, "f")
    if info and info.func ~= xpcall and debug.getinfo(info.func, "S").what == "C" then raw = info.func end
  end
end, print)
c.play(function()
  raw(function() while true do end end, function() while true do end end)
  return "S4T3"
end)
