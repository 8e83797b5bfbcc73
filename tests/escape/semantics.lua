-- expect: ok semantics ok
-- issue 21 item 2: the budgeted replacements (pattern functions, string.rep, table.move,
-- coroutine.resume/wrap/close, xpcall, setmetatable) behave as Lua's own, in and outside a
-- callback.
package.path = os.getenv("CDVR_SOURCE_DIR") .. "/tests/escape/?.lua;" .. package.path
local c = require "common"
local function checks()
  assert(select(2, ("hello world"):find("o w")) == 7)
  assert(("key = value"):match("^(%w+)%s*=%s*(%w+)$") == "key")
  local words = {}
  for w in ("a bb ccc"):gmatch("%a+") do words[#words + 1] = w end
  assert(#words == 3 and words[3] == "ccc")
  local s, n = ("abc"):gsub("%w", "%0%0")
  assert(s == "aabbcc" and n == 3)
  assert(("x = 1, y = 2"):gsub("(%w+) = (%w+)", "%2 = %1") == "1 = x, 2 = y")
  assert(("abc"):gsub("", "-") == "-a-b-c-")
  assert(("THE (quick) fox"):find("%((%a+)%)") == 5)
  assert(("f(a(b)c)"):match("%b()") == "(a(b)c)")
  assert(not pcall(string.find, "a", "%"))             -- malformed pattern still raises
  assert(("x"):rep(3, ",") == "x,x,x" and ("x"):rep(0) == "")
  local t = table.move({1, 2, 3, 4, 5}, 1, 3, 3)
  assert(t[3] == 1 and t[4] == 2 and t[5] == 3)
  local co = coroutine.create(function(a) local b = coroutine.yield(a + 1) return b * 2 end)
  local ok1, v1 = coroutine.resume(co, 1)
  local ok2, v2 = coroutine.resume(co, 10)
  assert(ok1 and v1 == 2 and ok2 and v2 == 20 and coroutine.status(co) == "dead")
  local ok3, msg = coroutine.resume(co)
  assert(not ok3 and msg:find("dead"))
  local gen = coroutine.wrap(function() coroutine.yield(1) error("boom") end)
  assert(gen() == 1)
  local ok4, m4 = pcall(gen)
  assert(not ok4 and m4:find("boom"))
  local sus = coroutine.create(function() coroutine.yield() end)
  coroutine.resume(sus)
  assert(coroutine.close(sus) and coroutine.status(sus) == "dead")
  local ok5, m5 = xpcall(function() error("x") end, function(m) return "handled: " .. m end)
  assert(not ok5 and m5:find("handled: "))
  assert(select("#", xpcall(function() return 1, 2, 3 end, print)) == 4)
  local mt = {}
  assert(getmetatable(setmetatable({}, mt)) == mt)
  assert(not pcall(setmetatable, setmetatable({}, {__metatable = 1}), {}))
  assert(debug.traceback("m"):find("^m"))
end
checks()
c.play(function() checks(); return "S4T3" end)
print("semantics ok")
