-- Shared by the misuse scripts (tests/test_misuse.sh runs each one as its own cdvr process).
local M = {}
M.dir = assert(os.getenv("CDVR_MISUSE_DIR"), "run through tests/test_misuse.sh")

-- A small two-variant store (S4T3 and raw) of a 12^3 x 6 sphere series.
function M.store(name)
  local vol = cdvr.generate("sphere", {dims = {12, 12, 12}, timesteps = 6})
  local path = M.dir .. "/" .. (name or "s") .. ".cdv"
  return assert(cdvr.encode(vol, {variants = {{S = 4, T = 3}, {codec = "raw"}}, stage2 = "none",
                                  path = path, progress = false})), vol
end

M.camera = {eye = {40, 5, 5}, center = {5, 5, 5}, up = {0, 0, 1}, fov = 30}

function M.player(st, extra)
  local opts = {store = st, tf = cdvr.tf("hot"), width = 16, height = 16, device = "cpu"}
  for k, v in pairs(extra or {}) do opts[k] = v end
  return cdvr.player(opts)
end

-- true when obj's methods refuse it as closed
function M.closed(obj, method)
  local ok, msg = pcall(obj[method], obj)
  return not ok and tostring(msg):find("closed") ~= nil
end

-- Loads or opens path through f, which may return nil, msg or raise; re-raises the message.
function M.refuse(f, ...)
  local ok, a, b = pcall(f, ...)
  if ok and a then error("loaded " .. tostring(a) .. ", expected a refusal") end
  error(ok and b or a, 0)
end

return M
