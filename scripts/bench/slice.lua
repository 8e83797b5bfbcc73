-- scripts/bench/slice.lua [--size N] [--runs N] [--data DIR]: 2D-texture slicing with and
-- without the per-slice level of detail of seed 002, against the CPU ray caster, on the engine
-- CT and Colin27, and against the OpenCL ray cast (the CPU one where this cdvr has no OpenCL),
-- all in the same run, the steady frames interleaved.
--
-- View: the seed's setup along the z stack, the eye on the stack's axis (0.3 half-extents off
-- centre in y) at distance D * h before the first slice, h = half the z extent (the seed's box
-- [-1, 1] has h = 1), D = 0.5 .. 1.5, looking at the centre, fov 90, N x N pixels (512).
-- Per view: the slicer's first frame (textures built and uploaded; the stack is evicted before by
-- slicing a 2x2x2 volume), then --runs rounds that each render one steady frame with LOD, one
-- without and one ray cast at matched sampling (step = slice spacing, default early
-- termination), the order rotated every round (first ray-cast frame untimed); medians. Images: PSNR of LOD against no LOD, and of each
-- against the ray caster.
-- CSV on stdout (progress on stderr when it is a terminal):
--   dataset,D,size,lod_bytes,full_bytes,bytes_saved_pct,lod_first_ms,nolod_first_ms,lod_ms,
--   nolod_ms,ray_ms,lod_over_nolod_time,nolod_over_ray_time,psnr_lod_vs_nolod,
--   psnr_nolod_vs_ray,psnr_lod_vs_ray,levels,renderer,ray_device
local common = dofile((arg and arg[0] and arg[0]:match("^(.*/)") or "./") .. "common.lua")

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

-- The renderers' steady frame times, interleaved: `runs` rounds, each calling every renderer
-- once, the order rotated by one per round; medians (ms) and each renderer's last image.
local function interleaved(renderers, runs)
  local ms, last = {}, {}
  for i = 1, #renderers do ms[i] = {} end
  for r = 1, runs do
    for j = 0, #renderers - 1 do
      local i = (r - 1 + j) % #renderers + 1
      local img, s = renderers[i]()
      ms[i][#ms[i] + 1], last[i] = s.ms, img
    end
  end
  local med = {}
  for i = 1, #renderers do med[i] = common.median(ms[i]) end
  return med, last
end

-- The OpenCL ray cast where this cdvr has it, else the CPU one.
local RAY_DEVICE = pcall(cdvr.render, evict, {tf = cdvr.tf("ct_bone"), camera = evict_cam,
                                              device = "cl"}) and "cl" or "cpu"

print("dataset,D,size,lod_bytes,full_bytes,bytes_saved_pct,lod_first_ms,nolod_first_ms,lod_ms," ..
      "nolod_ms,ray_ms,lod_over_nolod_time,nolod_over_ray_time,psnr_lod_vs_nolod," ..
      "psnr_nolod_vs_ray,psnr_lod_vs_ray,levels,renderer,ray_device")
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
    local function ray()
      return cdvr.render(v, {tf = tf, camera = cam, step = step, device = RAY_DEVICE})
    end
    cdvr.render(evict, {tf = tf, camera = evict_cam, method = "slice"})
    local _, lod_first = slice(true)()
    cdvr.render(evict, {tf = tf, camera = evict_cam, method = "slice"})
    local _, full_first = slice(false)()
    ray() -- first frame: kernel build, upload
    local med, last = interleaved({slice(true), slice(false), ray}, RUNS)
    local lod_img, full_img, ray_img = last[1], last[2], last[3]
    local lod_ms, full_ms, ray_ms = med[1], med[2], med[3]
    local p_lod = cdvr.compare(full_img, lod_img).psnr
    local p_full_ray = cdvr.compare(ray_img, full_img).psnr
    local p_lod_ray = cdvr.compare(ray_img, lod_img).psnr
    local ls, fs = lod_img:stats(), full_img:stats()
    print(string.format("%s,%.2f,%d,%d,%d,%.1f,%.1f,%.1f,%.1f,%.1f,%.1f,%.3f,%.3f,%.2f,%.2f,%.2f,%d..%d,%q,%s",
      ds.name, D, SIZE, ls.texture_bytes, fs.texture_bytes, 100 * (1 - ls.texture_bytes / fs.texture_bytes),
      lod_first.ms, full_first.ms, lod_ms, full_ms, ray_ms, lod_ms / full_ms, full_ms / ray_ms,
      p_lod, p_full_ray, p_lod_ray, ls.min_level, ls.max_level, ls.device, RAY_DEVICE))
    progress("%s D=%.2f: LOD %.0f%% fewer bytes, %.1f dB vs no LOD", ds.name, D,
             100 * (1 - ls.texture_bytes / fs.texture_bytes), p_lod)
    io.stdout:flush()
  end
end
