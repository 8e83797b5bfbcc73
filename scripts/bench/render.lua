-- scripts/bench/render.lua [path] [threads...]: CPU reference ray caster speed at 512x512.
-- Renders the engine CT (or the given u8 volume) with the ct_bone preset from a fixed orbit
-- view; per thread count (default: 1 and all cores) takes the median of 5 timed renders after
-- one warm-up, all in the same run. CSV on stdout:
--   dataset,width,height,threads,step,median_ms,fps,samples_per_s,speedup_vs_1thread
-- speedup_vs_1thread compares with the 1-thread median of this run (empty if 1 is not run).
local RUNS, SIZE, STEP = 5, 512, 0.5

local function default_path()
  local rel = "/ct/engine_256x256x128_u8.nrrd"
  local env = os.getenv("CDVR_SHARED_DATA")
  if env and env ~= "" then return env .. rel end
  for _, dir in ipairs{"../shared/data", "../../shared/data", cdvr.share_dir .. "/../../shared/data"} do
    local f = io.open(dir .. rel, "rb")
    if f then f:close() return dir .. rel end
  end
  return "../shared/data" .. rel
end

local function cores()
  local p = io.popen("getconf _NPROCESSORS_ONLN 2>/dev/null")
  local n = p and tonumber(p:read("l") or "")
  if p then p:close() end
  return n or 1
end

local function median(list)
  local s = {table.unpack(list)}
  table.sort(s)
  local n = #s
  return n % 2 == 1 and s[(n + 1) // 2] or 0.5 * (s[n // 2] + s[n // 2 + 1])
end

local progress = os.execute("test -t 2") and function(fmt, ...)
  io.stderr:write(string.format(fmt, ...), "\n")
end or function() end

local path = arg[1] or default_path()
local threads = {}
for i = 2, #arg do threads[#threads + 1] = assert(math.tointeger(tonumber(arg[i])), "thread count expected: " .. arg[i]) end
if #threads == 0 then
  threads = {1}
  if cores() > 1 then threads[2] = cores() end
end

local vol, err = cdvr.load(path)
if not vol then error(err, 0) end
local dataset = path:match("([^/]+)$"):gsub("%.nii%.gz$", ""):gsub("%.%w+$", "")
local tf = cdvr.tf("ct_bone")
local cam = cdvr.orbit_camera(vol, {azimuth = -60, elevation = 25, width = SIZE, height = SIZE})

print("dataset,width,height,threads,step,median_ms,fps,samples_per_s,speedup_vs_1thread")
local one_thread_ms
for _, n in ipairs(threads) do
  local opts = {tf = tf, camera = cam, step = STEP, threads = n}
  cdvr.render(vol, opts) -- warm-up: caches, page faults
  local times, samples = {}, 0
  for run = 1, RUNS do
    local _, st = cdvr.render(vol, opts)
    times[run], samples = st.ms, st.samples
    progress("threads %d run %d: %.1f ms", n, run, st.ms)
  end
  local ms = median(times)
  if n == 1 then one_thread_ms = ms end
  print(string.format("%s,%d,%d,%d,%g,%.2f,%.3f,%.4g,%s", dataset, SIZE, SIZE, n, STEP, ms,
                      1000 / ms, samples / (ms / 1000),
                      one_thread_ms and string.format("%.2f", one_thread_ms / ms) or ""))
end
