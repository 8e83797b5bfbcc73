-- Shared by the escape scripts (tests/test_escape.sh runs each as its own cdvr process).
local M = {}
M.dir = assert(os.getenv("CDVR_ESCAPE_DIR"), "run through tests/test_escape.sh")

-- A small two-variant store (S4T3 and raw) of a 12^3 x 6 sphere series.
function M.store()
  local vol = cdvr.generate("sphere", {dims = {12, 12, 12}, timesteps = 6})
  return assert(cdvr.encode(vol, {variants = {{S = 4, T = 3}, {codec = "raw"}}, stage2 = "none",
                                  path = M.dir .. "/s.cdv", progress = false})), vol
end

M.camera = {eye = {40, 5, 5}, center = {5, 5, 5}, up = {0, 0, 1}, fov = 30}

-- Plays 3 frames with a policy callback (and camera callback when given).
function M.play(policy, camera)
  local st = M.store()
  local p = cdvr.player{store = st, tf = cdvr.tf("hot"), width = 16, height = 16, device = "cpu",
                        callback_limit = 1000000, policy = policy,
                        camera = camera or cdvr.camera(M.camera)}
  return p:run{frames = 3}
end

-- Writes text to a file in the scratch directory; returns its path.
function M.write(name, text)
  local path = M.dir .. "/" .. name
  local f = assert(io.open(path, "wb"))
  f:write(text)
  f:close()
  return path
end

-- Calls f(...), which must raise; re-raises its message (so the runner checks it).
function M.refuse(f, ...)
  local ok, msg = pcall(f, ...)
  if ok then error("succeeded, expected an error", 0) end
  error(msg, 0)
end

-- True when the file exists.
function M.exists(path)
  local f = io.open(path, "rb")
  if f then f:close() end
  return f ~= nil
end

return M
