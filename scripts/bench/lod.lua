-- scripts/bench/lod.lua: the brick cache and level of detail (issue 26; cdvr/brick_cache.h)
-- against the full render of the same store, CSV on stdout.
--
--   cd scripts/bench && ../../build/cdvr lod.lua [--volume N] [--series N] [--timesteps T]
--        [--frames F] [--levels L] [--bricks B] [--pixels P] [--budgets 64,256,1024]
--        [--lods 0.5,1,2] [--repeats R] [--dir DIR] [--hvq PATH|none] [--parts volume,series,hvq]
--
-- Stores, made in DIR (default a temporary directory, removed at the end; reused when there):
-- a generated N^3 u8 volume (Marschner-Lobb, default N = 1024) and an N^3 x T series (default
-- 256^3 x 60, the sphere generator, which varies with t), both raw (level 0 lossless), bricked
-- B^3 (default 8) with L levels (default 4); and the engine CT (or --hvq PATH) as an hvq store,
-- bricked 8x8x4 with 3 levels, hvq at every level.
-- Volume and series: each row is one budget and lod_error; it renders F frames (default 1 for
-- the volume, 4 timesteps of the series) at P^2 pixels (default 512) on the cl device, full
-- render (cache off: the store's dense path) and through the cache (the brick march)
-- alternated A B A B, R repeats (default 3), after one warm-up each (the program build, the
-- cache's first decode); median frame times of both and their ratio (cached / full), the
-- resident bytes, the bricks per level, the image PSNR against the full render of the same
-- frame (the lowest over the frames), the process's peak host memory so far (VmHWM; on a CPU
-- device the device's memory is host memory too), the payload the device holds for the frame
-- (the cache's page table and bricks: the device memory of the volume) against the dense
-- frame's bytes, the load average at the row's end, and the samples (trilinear +
-- classification) both took over the frames.
-- hvq: the hvq store through the cache at budgets of a quarter of the dense volume (the whole
-- payload, tables included, within a quarter) and of the whole, alternated with the dense render of the hvq-decoded volume already in memory; then
-- (path "runs") 3R dense renders in a row (from the second on the device renders the same
-- frame again: its best case) against 3R cached ones at a quarter; and the store's own path
-- (cache off) alternated with the dense render.
local common = dofile((arg and arg[0] and arg[0]:match("^(.*/)") or "./") .. "common.lua")

local _, opt = common.parse_args(arg, {volume = "1024", series = "256", timesteps = "60",
  frames = "4", levels = "4", bricks = "8", pixels = "512", budgets = "64,256,1024",
  lods = "0.5,1,2", repeats = "3", dir = "", hvq = "", parts = "volume,series,hvq"})
local function int(k) return (assert(math.tointeger(tonumber(opt[k])), k)) end
local function list(s) local t = {} for x in s:gmatch("[^,]+") do t[#t + 1] = assert(tonumber(x)) end return t end
local budgets, lods = list(opt.budgets), list(opt.lods)
local parts = {}
for p in opt.parts:gmatch("[^,]+") do parts[p] = true end
local dir, own_dir = common.work_dir(opt.dir)

local function loadavg()
  local s = common.loadavg()
  return s:match("^(%S+ %S+ %S+)") or s
end

local function peak_mb()
  local f = io.open("/proc/self/status")
  if not f then return 0 end
  local s = f:read("a")
  f:close()
  return (tonumber(s:match("VmHWM:%s+(%d+)")) or 0) / 1024
end

local function make_store(name, gen, n, timesteps)
  local path = ("%s/%s_%d_%d_l%d.cdv"):format(dir, name, n, timesteps, int("levels"))
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
print("dataset,frames,budget_mb,lod_error,full_ms,cached_ms,ratio,resident_bytes,cache_bytes,"
      .. "bricks_per_level,psnr_vs_full,peak_host_mb,payload_bytes,dense_bytes,path,loadavg,"
      .. "encode_s,first_frame_ms,full_samples,cached_samples")

local function render(st, o, extra)
  local a = {}
  for k, v in pairs(o) do a[k] = v end
  for k, v in pairs(extra or {}) do a[k] = v end
  local t0 = cdvr.clock()
  local img, stats = cdvr.render(st, a)
  return img, stats, (cdvr.clock() - t0) * 1000
end

local function levels_of(info, stats)
  local per = {}
  for l = 0, info.levels and #info.levels - 1 or 0 do
    per[#per + 1] = tostring(stats["bricks_level" .. l] or 0)
  end
  return table.concat(per, "/")
end

-- One row: `full` and `cached` (functions of the frame index giving image, stats, ms)
-- alternated A B A B over the frames and repeats.
local function row(name, frames, budget, lod, info, full, cached, dense_bytes, encode_s)
  local ok, first = pcall(function() return select(3, cached(1)) end) -- warm-up: first decode
  if not ok then
    print(("%s,%d,%g,%g,error: %s"):format(name, frames, budget, lod, tostring(first):gsub(",", ";")))
    io.stdout:flush()
    return
  end
  local fms, cms, psnr, stats, fsamples, csamples = {}, {}, math.huge, nil, 0, 0
  for r = 1, int("repeats") do
    for f = 1, frames do
      local a, fs, ams = full(f)
      local b, s, bms = cached(f)
      stats = s
      if r == 1 then fsamples, csamples = fsamples + fs.samples, csamples + s.samples end
      fms[#fms + 1], cms[#cms + 1] = ams, bms
      if r == 1 then psnr = math.min(psnr, cdvr.compare(b, a).psnr) end
    end
  end
  local fm, cm = common.median(fms), common.median(cms)
  print(("%s,%d,%g,%g,%.1f,%.1f,%.2f,%d,%d,%s,%.2f,%.0f,%d,%d,%s,%s,%.1f,%.1f,%d,%d"):format(name,
        frames, budget, lod, fm, cm, cm / fm, stats.resident_bytes, stats.cache_bytes,
        levels_of(info, stats), psnr, peak_mb(), stats.payload_bytes, dense_bytes,
        stats.cache_path, loadavg(), encode_s, first, fsamples, csamples))
  io.stdout:flush()
end

local function bench(name, st, frames, encode_s)
  local info = st:info()
  local cam = cdvr.orbit_camera(info, {azimuth = 30, elevation = 20, width = PIX, height = PIX})
  local tf = cdvr.tf("hot")
  local base = {tf = tf, camera = cam, device = "cl"}
  local dense_bytes = info.dims[1] * info.dims[2] * info.dims[3]
  local function full(f) return render(st, base, {t = f}) end
  full(1) -- warm-up: program build
  for _, budget in ipairs(budgets) do
    for _, lod in ipairs(lods) do
      local extra = {cache = true, budget_mb = budget, lod_error = lod}
      row(name, frames, budget, lod, info, full, function(f)
        extra.t = f
        return render(st, base, extra)
      end, dense_bytes, encode_s)
    end
  end
end

-- hvq through the cache against the dense render of the hvq-decoded volume.
local function bench_hvq()
  local data = opt.hvq ~= "" and opt.hvq or common.shared_data() .. "/ct/engine_256x256x128_u8.nrrd"
  local path = ("%s/hvq_l3.cdv"):format(dir)
  local t0 = cdvr.clock()
  local encode_s = 0
  if not common.exists(path) then
    cdvr.encode(cdvr.load(data), {path = path, progress = false, bricks = {8, 8, 4}, levels = 3,
                                  variants = {{codec = "hvq", name = "hvq"}}}):close()
    encode_s = cdvr.clock() - t0
  end
  local st = cdvr.open(path)
  local info = st:info()
  local vol = st:decode(1, "hvq")
  local cam = cdvr.orbit_camera(info, {azimuth = 30, elevation = 20, width = PIX, height = PIX})
  local tf = cdvr.tf("ct_bone")
  local base = {tf = tf, camera = cam, device = "cl"}
  local dense_bytes = info.dims[1] * info.dims[2] * info.dims[3]
  local function dense(_) return render(vol, base) end
  dense(1)
  local store_path = function(_) return render(st, base, {variant = "hvq"}) end
  store_path(1)
  -- a quarter of the dense volume for the whole payload: the budget (voxels) less the page
  -- table and owner tables the payload adds
  local _, probe = render(st, base, {variant = "hvq", cache = true, budget_mb = dense_bytes / 4e6})
  local quarter_mb = (dense_bytes / 4 - (probe.payload_bytes - probe.resident_bytes)) / 1e6
  for _, budget in ipairs{quarter_mb, 4 * dense_bytes / 1e6} do
    for _, lod in ipairs{1} do
      row("hvq_" .. info.dims[1] .. "x" .. info.dims[2] .. "x" .. info.dims[3], 1, budget, lod,
          info, dense, function(_)
            return render(st, base, {variant = "hvq", cache = true, budget_mb = budget,
                                     lod_error = lod})
          end, dense_bytes, encode_s)
    end
  end
  -- runs instead of alternation: the dense render of the same frame again is its best case
  -- (the device keeps the frame and makes its tiled copy, raycast.cl); the cache at a quarter
  local quarter = {variant = "hvq", cache = true, budget_mb = quarter_mb, lod_error = 1}
  local rms, qms, qs = {}, {}, nil
  local n_run = 3 * int("repeats")
  for r = 1, n_run do rms[r] = select(3, dense(1)) end
  for r = 1, n_run do
    local _, s1, ms = render(st, base, quarter)
    qms[r], qs = ms, s1
  end
  print(("%s,%d,%g,1,%.1f,%.1f,%.2f,%d,%d,,,%.0f,%d,%d,runs,%s,%.1f,"):format("hvq_" ..
        info.dims[1] .. "x" .. info.dims[2] .. "x" .. info.dims[3], n_run, quarter.budget_mb,
        common.median(rms), common.median(qms), common.median(qms) / common.median(rms),
        qs.resident_bytes, qs.cache_bytes, peak_mb(), qs.payload_bytes, dense_bytes, loadavg(),
        encode_s))
  -- the store's own path (cache off) against the same dense render, for scale
  local sms, dms = {}, {}
  for r = 1, int("repeats") do
    dms[r] = select(3, dense(1))
    sms[r] = select(3, store_path(1))
  end
  print(("%s,1,store_path,,%.1f,%.1f,%.2f,,,,,%.0f,,%d,hvq_store,%s,%.1f,"):format("hvq_" ..
        info.dims[1] .. "x" .. info.dims[2] .. "x" .. info.dims[3], common.median(dms),
        common.median(sms), common.median(sms) / common.median(dms), peak_mb(), dense_bytes,
        loadavg(), encode_s))
  st:close()
end

io.stderr:write("loadavg before: " .. loadavg() .. "\n")
if parts.volume then
  local n = int("volume")
  local st, enc = make_store("ml", "ml", n, 1)
  bench(("volume_%d^3"):format(n), st, 1, enc)
  st:close()
  st = nil
  collectgarbage()
end
if parts.series then
  local s = int("series")
  local st, enc = make_store("sphere", "sphere", s, int("timesteps"))
  bench(("series_%d^3x%d"):format(s, int("timesteps")), st, math.min(int("frames"), int("timesteps")), enc)
  st:close()
  collectgarbage()
end
if parts.hvq then bench_hvq() end
io.stderr:write("loadavg after: " .. loadavg() .. "\n")
if own_dir then os.execute(("rm -rf %q"):format(dir)) end
