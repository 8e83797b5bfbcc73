-- scripts/bench/lod.lua: the brick cache and level of detail (issue 26; cdvr/brick_cache.h)
-- against the full render of the same store, CSV on stdout.
--
--   cd scripts/bench && ../../build/cdvr lod.lua [--volume N] [--series N] [--timesteps T]
--        [--frames F] [--levels L] [--bricks B] [--pixels P] [--budgets 64,256,1024]
--        [--lods 0.5,1,2] [--repeats R] [--dir DIR]
--
-- Two stores, made in DIR (default a temporary directory, removed at the end): a generated
-- N^3 u8 volume (Marschner-Lobb, default N = 1024) and an N^3 x T series (default 256^3 x 60,
-- the sphere generator, which varies with t), both raw (level 0 lossless), bricked B^3 (default
-- 8) with L levels (default 4). Each row renders F frames (default 1 for the volume, 4
-- timesteps of the series) at P^2 pixels (default 512) on the cl device through the cache at
-- one budget and lod_error, after one warm-up frame (the program build, the cache's first
-- decode), and gives the median frame time, the resident bytes, the bricks per level, the
-- image PSNR against the full render (cache off) of the same frame, and the process's peak
-- host memory so far (VmHWM; on a CPU device the device's memory is host memory) and device
-- bytes (the stream's buffers). The "full" rows are the dense render itself. loadavg on stderr.
local common = dofile((debug.getinfo(1, "S").source:match("^@(.*)/[^/]*$") or ".") .. "/common.lua")

local _, opt = common.parse_args(arg, {volume = "1024", series = "256", timesteps = "60",
  frames = "4", levels = "4", bricks = "8", pixels = "512", budgets = "64,256,1024",
  lods = "0.5,1,2", repeats = "3", dir = ""})
local function int(k) return (assert(math.tointeger(tonumber(opt[k])), k)) end
local function list(s) local t = {} for x in s:gmatch("[^,]+") do t[#t + 1] = assert(tonumber(x)) end return t end
local budgets, lods = list(opt.budgets), list(opt.lods)
local dir = opt.dir
local own_dir = dir == ""
if own_dir then
  dir = os.tmpname()
  os.remove(dir)
end
assert(os.execute(("mkdir -p %q"):format(dir)))

local function loadavg()
  local f = io.open("/proc/loadavg")
  local s = f and f:read("l") or "?"
  if f then f:close() end
  return s
end

local function peak_mb()
  local f = io.open("/proc/self/status")
  if not f then return 0 end
  local s = f:read("a")
  f:close()
  return (tonumber(s:match("VmHWM:%s+(%d+)")) or 0) / 1024
end

local function make_store(name, gen, n, timesteps)
  local path = ("%s/%s_%d_%d.cdv"):format(dir, name, n, timesteps)
  if common.exists(path) then return cdvr.open(path), 0 end
  local t0 = cdvr.clock()
  local v = cdvr.generate(gen, {dims = {n, n, n}, timesteps = timesteps})
  local b = int("bricks")
  local st = cdvr.encode(v, {path = path, progress = false, codec = "raw", stage2 = "none",
                             bricks = {b, b, b}, levels = int("levels")})
  v = nil
  collectgarbage()
  return st, cdvr.clock() - t0
end

local PIX = int("pixels")
local tf = cdvr.tf("hot")
print("dataset,frames,budget_mb,lod_error,median_ms,resident_bytes,cache_bytes,bricks_per_level,"
      .. "psnr_vs_full,peak_host_mb,device_bytes,encode_s")

local function bench(name, st, frames, encode_s)
  local info = st:info()
  local cam = cdvr.orbit_camera(info, {azimuth = 30, elevation = 20, width = PIX, height = PIX})
  local full, full_ms = {}, {}
  local function render(t, extra)
    local o = {t = t, tf = tf, camera = cam, device = "cl"}
    for k, v in pairs(extra or {}) do o[k] = v end
    local t0 = cdvr.clock()
    local img, stats = cdvr.render(st, o)
    return img, stats, (cdvr.clock() - t0) * 1000
  end
  render(1) -- warm-up: program build
  local stats_full
  for f = 1, frames do
    local ms = {}
    for r = 1, int("repeats") do
      full[f], stats_full, ms[r] = render(f)
    end
    full_ms[f] = common.median(ms)
  end
  print(("%s,%d,full,,%.1f,%d,,,inf,%.0f,%d,%.1f"):format(name, frames, common.median(full_ms),
        stats_full.volume_bytes, peak_mb(), stats_full.device_bytes, encode_s))
  io.stdout:flush()
  for _, budget in ipairs(budgets) do
    for _, lod in ipairs(lods) do
      local extra = {cache = true, budget_mb = budget, lod_error = lod}
      local ok, err = pcall(render, 1, extra) -- warm-up: first decode into the cache
      if not ok then
        print(("%s,%d,%g,%g,error: %s"):format(name, frames, budget, lod, tostring(err):gsub(",", ";")))
      else
        local ms, psnr, stats = {}, math.huge, nil
        for f = 1, frames do
          local img
          img, stats, ms[f] = render(f, extra)
          psnr = math.min(psnr, cdvr.compare(img, full[f]).psnr)
        end
        local per = {}
        for l = 0, info.levels and #info.levels - 1 or 0 do
          per[#per + 1] = tostring(stats["bricks_level" .. l] or 0)
        end
        print(("%s,%d,%g,%g,%.1f,%d,%d,%s,%.2f,%.0f,%d,"):format(name, frames, budget, lod,
              common.median(ms), stats.resident_bytes, stats.cache_bytes, table.concat(per, "/"),
              psnr, peak_mb(), stats.device_bytes))
      end
      io.stdout:flush()
    end
  end
end

io.stderr:write("loadavg before: " .. loadavg() .. "\n")
local n = int("volume")
local st, enc = make_store("ml", "ml", n, 1)
bench(("volume_%d^3"):format(n), st, 1, enc)
st:close()
st = nil
collectgarbage()
local s = int("series")
st, enc = make_store("sphere", "sphere", s, int("timesteps"))
bench(("series_%d^3x%d"):format(s, int("timesteps")), st, math.min(int("frames"), int("timesteps")), enc)
st:close()
io.stderr:write("loadavg after: " .. loadavg() .. "\n")
if own_dir then os.execute(("rm -rf %q"):format(dir)) end
