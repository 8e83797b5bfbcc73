-- scripts/bench/slice.lua [--size N] [--runs N] [--data DIR]: 2D-texture slicing with and
-- without the per-slice level of detail of seed 002, against the CPU ray caster, on the engine
-- CT and Colin27, all in the same run.
--
-- View: the seed's setup along the z stack, the eye on the stack's axis (0.3 half-extents off
-- centre in y) at distance D * h before the first slice, h = half the z extent (the seed's box
-- [-1, 1] has h = 1), D = 0.5 .. 1.5, looking at the centre, fov 90, N x N pixels (512).
-- Per view: the slicer's first frame (textures built and uploaded; the stack is evicted before by
-- slicing a 2x2x2 volume) and its steady frame time (median of --runs frames with the textures
-- reused), with LOD and without; the ray caster's median frame time at matched sampling (step =
-- slice spacing, default early termination). Images: PSNR of LOD against no LOD, and of each
-- against the ray caster.
-- CSV on stdout (progress on stderr when it is a terminal):
--   dataset,D,size,lod_bytes,full_bytes,bytes_saved_pct,lod_first_ms,nolod_first_ms,lod_ms,
--   nolod_ms,ray_ms,lod_over_nolod_time,nolod_over_ray_time,psnr_lod_vs_nolod,
--   psnr_nolod_vs_ray,psnr_lod_vs_ray,levels,renderer
local common = dofile((debug.getinfo(1, "S").source:match("^@(.*/)") or "./") .. "common.lua")

local _, opt = common.parse_args(arg, {size = "512", runs = "5"})
local SIZE, RUNS = assert(math.tointeger(tonumber(opt.size))), assert(math.tointeger(tonumber(opt.runs)))
local data = opt.data or common.shared_data()
local progress = os.execute("test -t 2") and function(fmt, ...)
  io.stderr:write(string.format(fmt, ...), "\n")
end or function() end

if not cdvr.have_gl then
  io.stderr:write("slice.lua: this cdvr has no GL (CDVR_WITH_GL)\n")
  os.exit(1)
end

local datasets = {
  {name = "engine", path = data .. "/ct/engine_256x256x128_u8.nrrd", tf = "ct_bone"},
  {name = "colin27", path = data .. "/mri/colin27_t1_301x370x316_u8.nii.gz", tf = "mri"},
}
local evict = cdvr.generate("box", {dims = {2, 2, 2}})
local evict_cam = cdvr.orbit_camera(evict, {width = 8, height = 8})

local function camera_at(v, D)
  local d, sp, org = {v:dims()}, {v:spacing()}, {v:origin()}
  local lo, hi, c = {}, {}, {}
  for a = 1, 3 do
    lo[a], hi[a] = org[a], org[a] + (d[a] - 1) * sp[a]
    c[a] = 0.5 * (lo[a] + hi[a])
  end
  local h = 0.5 * (hi[3] - lo[3])
  return cdvr.camera{eye = {c[1], c[2] + 0.3 * h, lo[3] - D * h}, center = c, up = {0, 1, 0},
                     fov = 90, width = SIZE, height = SIZE}
end

-- median frame time of `runs` calls of render(), after the first (which is returned too)
local function timed(render, runs)
  local first_img, first = render()
  local ms = {}
  for i = 1, runs do
    local _, s = render()
    ms[i] = s.ms
  end
  return first_img, first, common.median(ms)
end

print("dataset,D,size,lod_bytes,full_bytes,bytes_saved_pct,lod_first_ms,nolod_first_ms,lod_ms," ..
      "nolod_ms,ray_ms,lod_over_nolod_time,nolod_over_ray_time,psnr_lod_vs_nolod," ..
      "psnr_nolod_vs_ray,psnr_lod_vs_ray,levels,renderer")
for _, ds in ipairs(datasets) do
  if not common.exists(ds.path) then
    io.stderr:write("slice.lua: missing " .. ds.path .. " (set CDVR_SHARED_DATA)\n")
    os.exit(1)
  end
  local v = cdvr.load(ds.path)
  local tf = cdvr.tf(ds.tf)
  local step = select(3, v:spacing())
  for _, D in ipairs{0.5, 0.75, 1.0, 1.25, 1.5} do
    local cam = camera_at(v, D)
    local function slice(lod)
      return function() return cdvr.render(v, {tf = tf, camera = cam, method = "slice", lod = lod}) end
    end
    cdvr.render(evict, {tf = tf, camera = evict_cam, method = "slice"})
    local lod_img, lod_first, lod_ms = timed(slice(true), RUNS)
    cdvr.render(evict, {tf = tf, camera = evict_cam, method = "slice"})
    local full_img, full_first, full_ms = timed(slice(false), RUNS)
    local ray_img, _, ray_ms = timed(function()
      return cdvr.render(v, {tf = tf, camera = cam, step = step})
    end, math.max(1, RUNS // 2))
    local p_lod = cdvr.compare(full_img, lod_img).psnr
    local p_full_ray = cdvr.compare(ray_img, full_img).psnr
    local p_lod_ray = cdvr.compare(ray_img, lod_img).psnr
    local ls, fs = lod_img:stats(), full_img:stats()
    print(string.format("%s,%.2f,%d,%d,%d,%.1f,%.1f,%.1f,%.1f,%.1f,%.1f,%.3f,%.3f,%.2f,%.2f,%.2f,%d..%d,%q",
      ds.name, D, SIZE, ls.texture_bytes, fs.texture_bytes, 100 * (1 - ls.texture_bytes / fs.texture_bytes),
      lod_first.ms, full_first.ms, lod_ms, full_ms, ray_ms, lod_ms / full_ms, full_ms / ray_ms,
      p_lod, p_full_ray, p_lod_ray, ls.min_level, ls.max_level, ls.device))
    progress("%s D=%.2f: LOD %.0f%% fewer bytes, %.1f dB vs no LOD", ds.name, D,
             100 * (1 - ls.texture_bytes / fs.texture_bytes), p_lod)
    io.stdout:flush()
  end
end
