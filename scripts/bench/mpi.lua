-- scripts/bench/mpi.lua - distributed playback (DESIGN.md section 12): frames per second and
-- per-stage times for 1, 2 and 4 MPI ranks in each mode (distribute="time", "bricks"),
-- against the one-process player measured in the same run, and the compositing time per
-- frame. CSV on stdout.
--
--   build/cdvr scripts/bench/mpi.lua [--frames 30] [--ranks 1,2,4] [--size 256] [--big 0|1]
--                                    [--variants raw,S4T3] [--repeats 3] [--vf 1|0]
--
-- The script drives itself: run plainly, it encodes the stores and starts
-- `mpirun -np N build/cdvr scripts/bench/mpi.lua --worker ...` for every configuration
-- (CDVR_MPIEXEC names the launcher; as root it adds --allow-run-as-root); each worker's rank 0
-- prints one CSV line. Data: the largest series of ../shared/data (viscous fingers, 64^3 x 60,
-- bricks 4x4x4) and, with --big 1, a generated 512^3 x 20 series (a moving sphere, bricks
-- 4x4x4; about 2.7 GB in memory while encoding and 2.7 GB on disk).
--
-- Columns: dataset, variant, mode (none = the one-process player, the baseline), ranks,
-- frames, fps (time: frames of all ranks over the slowest rank's wall time; bricks: frames
-- shown by rank 0; none: the player's), fps_ratio (fps / baseline fps, median of the
-- repeats), then per-frame medians (bricks: of the slowest rank in each frame) of read, unzip,
-- decode, render (b1, b1', b3, b5 in ms), composite_ms (IceT blending, waiting excluded),
-- wait_ms (waiting for the other ranks' frames), bricks_read (all ranks), and est_fps: what N
-- machines would give, from the one-rank stage times of the same mode (time: N x the
-- one-rank fps; bricks: 1000 / (one-rank frame work / N + composite_ms measured with N)).
--
-- On one 2-core machine N ranks share two cores: the figures show correctness and the
-- overheads (composite, waiting, per-rank fixed costs), not speed-up.
-- arg[0], not debug.getinfo: under cdvr's script runner the main chunk's frame is a C frame
local common = dofile((arg and arg[0] and arg[0]:match("^(.*/)") or "./") .. "common.lua")

local function split(s)
  local out = {}
  for x in s:gmatch("[^,]+") do out[#out + 1] = x end
  return out
end

local _, opt = common.parse_args(arg, {frames = "30", ranks = "1,2,4", size = "256", big = "0",
                                       variants = "raw,S4T3", repeats = "3", vf = "1"})

local function median_of(rows, key)
  local v = {}
  for _, r in ipairs(rows) do v[#v + 1] = r[key] end
  return common.median(v)
end

-- ---- worker: one configuration under mpirun ----------------------------------------------
if opt.worker then
  local store, variant, mode, frames, size = opt.worker, opt.variant, opt.mode,
                                              tonumber(opt.frames), tonumber(opt.size)
  local st = assert(cdvr.open(store))
  local info = st:info()
  local c, ext = {}, 0
  for a = 1, 3 do
    c[a] = info.origin[a] + 0.5 * (info.dims[a] - 1) * info.spacing[a]
    ext = math.max(ext, (info.dims[a] - 1) * info.spacing[a])
  end
  local tf = cdvr.tf{{0, 0, 0, 0, 0}, {40, .2, .3, .9, 0}, {90, .9, .6, .3, .08}, {255, 1, 1, .9, .3}}
  local n = cdvr.mpi.size()
  -- big volumes: one group in flight per queue (each holds every brick's buffers)
  local ring = info.dims[1] * info.dims[2] * info.dims[3] > (1 << 26) and 1 or 3
  local p = cdvr.player{store = st, tf = tf, device = "cpu", variant = variant, width = size,
                        height = size, loop = true, distribute = mode,
                        threads = math.max(1, 2 // n), ring = ring,
                        camera = cdvr.path.orbit{center = c, distance = 2.2 * ext, period = frames,
                                                 elevation = 20}}
  p:run{frames = math.min(3, frames)}          -- warm-up: page cache, allocations
  local r = p:run{frames = frames}
  p:close()
  if cdvr.mpi.rank() ~= 0 then return end   -- (not os.exit: every rank must reach MPI_Finalize)
  -- per frame: the slowest rank's stage times (bricks), else the frame's own row
  local per_frame, stages = {}, {"read_ms", "unzip_ms", "decode_ms", "render_ms", "composite_ms",
                                 "wait_ms", "bricks_read", "work_ms"}
  for _, row in ipairs(r.frames) do
    assert(not row.error, row.error)
    local f = per_frame[row.frame] or {}
    per_frame[row.frame] = f
    local work = row.read_ms + row.unzip_ms + row.upload_ms + row.decode_ms + row.setup_ms + row.render_ms
    for _, k in ipairs(stages) do
      local v = k == "work_ms" and work or row[k]
      if k == "bricks_read" then f[k] = (f[k] or 0) + v else f[k] = math.max(f[k] or 0, v) end
    end
  end
  local list = {}
  for _, f in pairs(per_frame) do list[#list + 1] = f end
  local med = {}
  for _, k in ipairs(stages) do med[k] = median_of(list, k) end
  print(("RESULT,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.1f,%.3f"):format(r.fps, r.wall_ms,
    med.read_ms, med.unzip_ms, med.decode_ms, med.render_ms, med.composite_ms, med.wait_ms,
    med.bricks_read, med.work_ms))
  return
end

-- ---- driver ------------------------------------------------------------------------------
local exe = arg[-1] or "build/cdvr"
local script = arg[0]
local mpirun = os.getenv("CDVR_MPIEXEC") or "mpirun"
local root = io.popen("id -u"):read("l") == "0"
-- --bind-to none: Open MPI binds each rank to one core by default, which would halve a lone
-- rank's two render threads against the one-process baseline
local mpi_flags = "--oversubscribe --bind-to none" .. (root and " --allow-run-as-root" or "")
local frames, size = tonumber(opt.frames), tonumber(opt.size)
local tmp = os.tmpname()
os.remove(tmp)
assert(os.execute(("mkdir -p %q"):format(tmp)))
local function say(fmt, ...)
  io.stderr:write((fmt .. "\n"):format(...))
end

local datasets = {}
local vf = common.shared_data() .. "/series/viscousfingers/vf_t%03d.nrrd"
if opt.vf == "0" then
  say("viscous fingers skipped (--vf 0)")
elseif common.exists(vf:format(40)) then
  local s = assert(cdvr.load_series(vf, {first = 40, count = 60}))
  local q = s:quantize{lo = 0, hi = 125}
  s = nil
  datasets[#datasets + 1] = {name = "viscousfingers_64x60", volume = q}
else
  say("viscous fingers not found under %s: skipped", common.shared_data())
end
if opt.big == "1" then
  datasets[#datasets + 1] = {name = "sphere_512x20", make = function()
    return cdvr.generate("sphere", {dims = {512, 512, 512}, timesteps = 20, value = 200, radius = 0.6})
  end}
end

local function run(cmd)
  local p = io.popen(cmd .. " 2>&1")
  local out = p:read("a")
  local ok = p:close()
  local line = out:match("RESULT,([^\n]*)")
  if not ok or not line then
    say("FAILED: %s\n%s", cmd, out)
    return nil
  end
  local v = {}
  for x in line:gmatch("[^,]+") do v[#v + 1] = tonumber(x) end
  return {fps = v[1], wall_ms = v[2], read_ms = v[3], unzip_ms = v[4], decode_ms = v[5],
          render_ms = v[6], composite_ms = v[7], wait_ms = v[8], bricks_read = v[9], work_ms = v[10]}
end

local function worker_cmd(n, store, variant, mode)
  local args = ("%q --worker %q --variant %s --mode %s --frames %d --size %d"):format(
    script, store, variant, mode, frames, size)
  if mode == "none" then return ("%q %s"):format(exe, args) end
  return ("%q %s -np %d %q %s"):format(mpirun, mpi_flags, n, exe, args)
end

print("dataset,variant,mode,ranks,frames,fps,fps_ratio,read_ms,unzip_ms,decode_ms,render_ms," ..
      "composite_ms,wait_ms,bricks_read,est_fps")
if not cdvr.mpi.built then
  say("this cdvr is built without MPI (-DCDVR_WITH_MPI=ON): only the one-process baseline runs")
end
for _, ds in ipairs(datasets) do
  local vol = ds.volume or ds.make()
  local path = ("%s/%s.cdv"):format(tmp, ds.name)
  say("encoding %s", ds.name)
  local variants = {}
  for _, v in ipairs(split(opt.variants)) do
    variants[#variants + 1] = v == "raw" and {codec = "raw"} or
      {codec = "pvtc", S = tonumber(v:match("S(%d)")), T = tonumber(v:match("T(%d)"))}
  end
  assert(cdvr.encode(vol, {variants = variants, bricks = {4, 4, 4}, stage2 = "lzo", path = path})):close()
  vol, ds.volume = nil, nil
  collectgarbage()
  local names = assert(cdvr.open(path)):variants()
  for _, variant in ipairs(names) do
    local configs = {{"none", 1}}
    for _, mode in ipairs(cdvr.mpi.built and {"time", "bricks"} or {}) do
      for _, n in ipairs(split(opt.ranks)) do configs[#configs + 1] = {mode, tonumber(n)} end
    end
    -- every configuration repeatedly, interleaved, so that load changes hit all alike
    local results = {}
    for rep = 1, tonumber(opt.repeats) do
      for i, c in ipairs(configs) do
        say("%s %s %s x%d (repeat %d)", ds.name, variant, c[1], c[2], rep)
        local r = run(worker_cmd(c[2], path, variant, c[1]))
        if r then
          results[i] = results[i] or {}
          table.insert(results[i], r)
        end
      end
    end
    local med = {}
    for i in ipairs(configs) do
      if results[i] then
        med[i] = {}
        for _, k in ipairs{"fps", "read_ms", "unzip_ms", "decode_ms", "render_ms", "composite_ms",
                           "wait_ms", "bricks_read", "work_ms"} do
          med[i][k] = median_of(results[i], k)
        end
      end
    end
    local base = med[1] and med[1].fps
    local one = {}  -- one-rank results per mode, for the estimates
    for i, c in ipairs(configs) do
      if med[i] and c[2] == 1 then one[c[1]] = med[i] end
    end
    for i, c in ipairs(configs) do
      local m = med[i]
      if m then
        local mode, n = c[1], c[2]
        local est = m.fps
        if mode == "time" and one.time then
          est = n * one.time.fps
        elseif mode == "bricks" and one.bricks then
          est = 1000 / (one.bricks.work_ms / n + m.composite_ms)
        end
        print(("%s,%s,%s,%d,%d,%.2f,%.3f,%.2f,%.2f,%.2f,%.2f,%.3f,%.2f,%.0f,%.2f"):format(ds.name,
          variant, mode, n, frames, m.fps, base and m.fps / base or 0 / 0, m.read_ms, m.unzip_ms,
          m.decode_ms, m.render_ms, m.composite_ms, m.wait_ms, m.bricks_read, est))
        io.stdout:flush()
      end
    end
  end
  os.remove(path)
end
os.execute(("rm -rf %q"):format(tmp))
