-- scripts/bench/lod_async.lua: the brick cache's asynchronous residency (issue 26; cdvr_brick_
-- cache_set_async, player cache_async=true) against the synchronous cache, on a camera jump.
-- CSV on stdout, loadavg on stderr.
--
--   cd scripts/bench && ../../build/cdvr lod_async.lua [--volume N] [--levels L] [--bricks B]
--        [--pixels P] [--device cpu|cl] [--codec raw|hvq|...] [--lod 1] [--repeats R] [--dir DIR]
--        [--series T]
--
-- A generated N^3 u8 volume (Marschner-Lobb, default 256), bricked B^3 (default 8) with L
-- levels (default 4), one variant of --codec (default hvq, whose C decoder is slower than raw's
-- copy). Per repeat and mode (sync, async; alternating), a fresh player through the cache
-- (budget 1024 MB, lod_error --lod) plays one frame from afar (every brick at a coarse level;
-- the warm-up), then jumps to a near view: the row gives that frame's time (frame_ms: the
-- cache's decodes and the render), its bricks per level and bricks_coarser, then (async)
-- how many one-frame runs and how much wall time until the view is refined (bricks_coarser
-- 0), and the PSNR of the frame right after the jump and of the refined frame against the
-- synchronous frame of the same view. With --series T > 0, playback rows follow: an N^3 x T
-- series (the sphere generator) played once through, near view, per mode: the median frame
-- time (frame_ms) and setup_ms, and how many frames had every brick at its chosen level
-- (bricks_coarser 0; async prefetches the next timestep, cdvr_brick_cache_set_next).
local common = dofile((arg and arg[0] and arg[0]:match("^(.*/)") or "./") .. "common.lua")

local _, opt = common.parse_args(arg, {volume = "256", levels = "4", bricks = "8", pixels = "256",
  device = "cpu", codec = "hvq", lod = "1", repeats = "3", dir = "", series = "0"})
local function int(k) return (assert(math.tointeger(tonumber(opt[k])), k)) end
local dir, own_dir = common.work_dir(opt.dir)

local n, b = int("volume"), int("bricks")
local path = ("%s/ml_%d_%s_b%d_l%d.cdv"):format(dir, n, opt.codec, b, int("levels"))
local st
if common.exists(path) then
  st = cdvr.open(path)
else
  local variant = {codec = opt.codec}
  st = cdvr.encode(cdvr.generate("ml", {dims = {n, n, n}}),
                   {path = path, progress = false, stage2 = "none", variants = {variant},
                    bricks = {b, b, b}, levels = int("levels")})
end
local tf = cdvr.tf("ct_bone")
local p = int("pixels")
local far = cdvr.orbit_camera(st, {azimuth = 30, elevation = 20, distance = 40 * n, width = p,
                                   height = p})
local near = cdvr.orbit_camera(st, {azimuth = 30, elevation = 20, zoom = 1.6, width = p, height = p})
local lod = tonumber(opt.lod)

local function level_counts(row)
  local t = {}
  for l = 0, int("levels") - 1 do t[#t + 1] = tostring(row["bricks_level" .. l] or 0) end
  return table.concat(t, "/")
end

-- One row: a fresh player, the far warm-up frame, the jump, then (async) until refined.
local sync_image
local function run(mode)
  local calls, images = 0, {}
  local pl = cdvr.player{store = st, tf = tf, device = opt.device, cache = true,
                         cache_async = mode == "async", budget_mb = 1024, lod_error = lod,
                         pipeline = false, width = p, height = p,
                         camera = function()
                           calls = calls + 1
                           return calls == 1 and far or near
                         end,
                         frame = function(_, img) images[#images + 1] = img end}
  pl:run{frames = 1}
  local t0 = cdvr.clock()
  local jump = pl:run{frames = 1}.frames[1]
  assert(not jump.error, jump.error)
  local runs, refined_ms, last = 1, 0, jump
  while mode == "async" and last.bricks_coarser > 0 and runs < 500 do
    last = pl:run{frames = 1}.frames[1]
    runs = runs + 1
  end
  refined_ms = (cdvr.clock() - t0) * 1000
  pl:close()
  if mode == "sync" then sync_image = images[#images] end
  local function psnr(img)
    return sync_image and cdvr.compare(img, sync_image).psnr or 0 / 0
  end
  return jump, last, runs, refined_ms, psnr(images[2]), psnr(images[#images])
end

print("mode,repeat,jump_frame_ms,jump_render_ms,jump_setup_ms,jump_bricks_per_level,jump_bricks_coarser,"
      .. "runs_to_refined,ms_to_refined,refined_bricks_per_level,jump_psnr_vs_sync,refined_psnr_vs_sync")
io.stderr:write("loadavg before: " .. common.loadavg() .. "\n")
run("sync") -- the reference image of the near view (and a warm-up)
for r = 1, int("repeats") do
  for _, mode in ipairs{"sync", "async"} do
    local jump, last, runs, ms, jump_psnr, refined_psnr = run(mode)
    print(("%s,%d,%.1f,%.1f,%.1f,%s,%d,%d,%.1f,%s,%.2f,%.2f"):format(mode, r, jump.frame_ms,
          jump.render_ms, jump.setup_ms, level_counts(jump), jump.bricks_coarser, runs, ms,
          level_counts(last), jump_psnr, refined_psnr))
  end
end
local steps = int("series")
if steps > 0 then
  local spath = ("%s/sphere_%d_%d_%s_b%d_l%d.cdv"):format(dir, n, steps, opt.codec, b, int("levels"))
  local series = common.exists(spath) and cdvr.open(spath) or
    cdvr.encode(cdvr.generate("sphere", {dims = {n, n, n}, timesteps = steps}),
                {path = spath, progress = false, stage2 = "none", variants = {{codec = opt.codec}},
                 bricks = {b, b, b}, levels = int("levels")})
  local view = cdvr.orbit_camera(series, {azimuth = 30, elevation = 20, zoom = 1.6, width = p,
                                          height = p})
  local function median(t) table.sort(t) return t[(#t + 1) // 2] end
  print("mode,repeat,frames,median_frame_ms,median_setup_ms,frames_complete")
  for r = 1, int("repeats") do
    for _, mode in ipairs{"sync", "async"} do
      local pl = cdvr.player{store = series, tf = tf, device = opt.device, cache = true,
                             cache_async = mode == "async", budget_mb = 1024, lod_error = lod,
                             camera = view, width = p, height = p}
      local rows = pl:run{frames = steps}.frames
      pl:close()
      local fm, sm, complete = {}, {}, 0
      for _, row in ipairs(rows) do
        assert(not row.error, row.error)
        fm[#fm + 1], sm[#sm + 1] = row.frame_ms, row.setup_ms
        complete = complete + (row.bricks_coarser == 0 and 1 or 0)
      end
      print(("%s,%d,%d,%.1f,%.1f,%d"):format(mode, r, #rows, median(fm), median(sm), complete))
    end
  end
  series:close()
end
io.stderr:write("loadavg after: " .. common.loadavg() .. "\n")
st:close()
if own_dir then os.execute(("rm -rf %q"):format(dir)) end
