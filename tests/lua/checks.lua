-- tests/lua/checks.lua - counted checks shared by the Lua tests (not a test itself):
--   local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
--   local check, raises = checks.check, checks.raises
--   ...
--   checks.finish()  -- prints "N passed, N failed"; exits 1 when a check failed
local M = {passed = 0, failed = 0}

-- Counts cond; a failure writes msg and the caller's traceback to stderr and goes on.
function M.check(cond, msg)
  if cond then
    M.passed = M.passed + 1
  else
    M.failed = M.failed + 1
    io.stderr:write(debug.traceback("check failed: " .. tostring(msg), 2), "\n")
  end
end

-- f() must raise, with pattern (plain text) in its message when pattern is given.
function M.raises(f, pattern, what)
  local ok, err = pcall(f)
  M.check(not ok and (not pattern or tostring(err):find(pattern, 1, true)),
          what .. ": expected an error" .. (pattern and (" with '" .. pattern .. "'") or "") ..
          ", got " .. tostring(err))
end

-- f() must raise, with every string of parts (plain text) in its message.
function M.raises_all(f, parts, what)
  local ok, msg = pcall(f)
  M.check(not ok, what .. ": expected an error")
  for _, part in ipairs(parts) do
    M.check(not ok and tostring(msg):find(part, 1, true) ~= nil,
            what .. ": message '" .. tostring(msg) .. "' lacks '" .. part .. "'")
  end
end

-- Prints the counts (with note after them, if given); exits 1 when a check failed.
function M.finish(note)
  print(("%d passed, %d failed%s"):format(M.passed, M.failed, note or ""))
  if M.failed > 0 then os.exit(1) end
end

return M
