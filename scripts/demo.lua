-- scripts/demo.lua: the README's main job, on the bundled data (share/data), no ../shared.
-- 1. A still of the bundled head CT (VTK's "headsq", in Hounsfield units) with 3D Slicer's
--    CT-Bone preset and its shading, a colour bar in HU and orientation letters, written as
--    out/demo/head_ct.png and .jpg; beside it the same view unshaded and as a maximum intensity
--    projection (head_ct_flat.png, head_ct_mip.png).
-- 2. The bundled 4D ASL MRI series (64x64x24, 25 timesteps): encoded in three variants, played
--    back as a maximum intensity projection under the closed-loop rate-control policy along an
--    orbit camera path, frames written to out/demo/NNNN.png, an annotated still of timestep 2
--    (asl_t02.png: colour bar, axes, time), and the speed-against-error table. The interactive
--    run reads through an emulated slow disk (--read-mbps, default 1.5 MB/s, like a network
--    share) so the policy has to trade quality for speed.
--   build/cdvr scripts/demo.lua [--out DIR] [--frames N] [--target-fps F] [--read-mbps M] [--size S]
local opt = {out = "out/demo", frames = "25", ["target-fps"] = "30", ["read-mbps"] = "1.5", size = "512"}
for i = 1, #arg, 2 do opt[(arg[i] or ""):gsub("^%-%-", "")] = arg[i + 1] end
os.execute(('mkdir -p "%s"'):format(opt.out))

-- Part 1: the head CT. Its values are Hounsfield units, so an absolute preset applies as it is.
local ct_path = cdvr.share_dir .. "/data/headsq_64x64x93_i16.nrrd"
local ct = assert(cdvr.load(ct_path))
local cx, cy, cz = ct:dims()
local clo, chi = ct:range()
print(("data: %s  %dx%dx%d %s, %.0f .. %.0f HU"):format(ct_path:match("[^/]+$"), cx, cy, cz,
  ct:type(), clo, chi))
local size = tonumber(opt.size)
local ct_cam = cdvr.orbit_camera(ct, {azimuth = -60, elevation = 15, width = size, height = size, zoom = 1.15})
local bone = cdvr.tf("CT-Bone")
local stills = {
  {"head_ct", bone, bone:shade(), "CT-Bone, shaded"}, -- the preset's shading settings
  {"head_ct_flat", bone, {}, "CT-Bone, unshaded"},
  {"head_ct_mip", cdvr.tf("grayscale", {range = {0, 2000}}), {blend = "max"}, "CT, MIP"},
}
for _, s in ipairs(stills) do
  local o = {tf = s[2], camera = ct_cam, device = "cpu"}
  for k, v in pairs(s[3]) do o[k] = v end
  local img = cdvr.render(ct, o)
  img:annotate{colorbar = true, tf = s[2], volume = ct, unit = "HU", axes = true, camera = ct_cam,
               title = s[4]}
  img:save(opt.out .. "/" .. s[1] .. ".png")
  if s[1] == "head_ct" then img:save(opt.out .. "/head_ct.jpg", {quality = 90}) end
end
print(("  %s/head_ct.png (and .jpg), head_ct_flat.png, head_ct_mip.png"):format(opt.out))
print()

-- Part 2: the ASL series.
local data = cdvr.share_dir .. "/data/mpld_asl_64x64x24x25_f32.nii.gz"
local series = assert(cdvr.load(data))
local nx, ny, nz = series:dims()
local lo, hi = series:range()
-- Timestep 1 is the M0 (proton density) image, twice as bright as the labelled timesteps
-- (max about 2839 against 975..1415, most of their brain below 1100): a window over all of it
-- would leave those dark. The window [0, 1100] shows every labelled timestep in the colour
-- map's bright half, clipping their hottest voxels and much of M0 (the count is printed).
local wlo, whi = 0, math.min(hi, 1100)
local q, qinfo = series:quantize{lo = wlo, hi = whi}
print(("data: %s  %dx%dx%d x %d timesteps (%s), range [%.1f, %.1f], window [%g, %g], %d values clipped, %d NaN"):format(
  data:match("[^/]+$"), nx, ny, nz, series:timesteps(), series:type(), lo, hi, wlo, whi, qinfo.clipped, qinfo.nan))

local store_path = opt.out .. "/demo.cdv"
local st = assert(cdvr.encode(q, {variants = {{S = 1, T = 3}, {S = 4, T = 3}, {codec = "raw"}},
                                  stage2 = "lzo", path = store_path}))
local info = st:info()

-- maximum intensity projection, matplotlib's inferno over the window, in signal units
local tf = cdvr.tf("inferno", {range = {wlo, whi}})
local frames = tonumber(opt.frames)
-- orbit around the centre of the volume's oriented box in world (patient, mm) coordinates, at
-- the distance where orbit_camera's framing (the box at 90% of the view) is, a little closer
local x0, x1, y0, y1, z0, z1 = q:bounds()
local center = {(x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2}
local fit = cdvr.orbit_camera(q, {azimuth = 0, elevation = 20, width = 256, height = 256, zoom = 1.4})
local ex, ey, ez = table.unpack(fit.eye)
local path = cdvr.path.orbit{center = center, elevation = 20, period = frames, fov = 30,
  distance = math.sqrt((ex - center[1])^2 + (ey - center[2])^2 + (ez - center[3])^2)}

-- an annotated still of timestep 2 (the first labelled one)
local still_cam = path:camera(1, size, size)
local still = cdvr.render(q, {tf = tf, camera = still_cam, t = 2, blend = "max", device = "cpu"})
still:annotate{colorbar = true, tf = tf, volume = q, axes = true, camera = still_cam, space = "RAS",
               title = "ASL, MIP", time = 2}
still:save(opt.out .. "/asl_t02.png")

local p = cdvr.player{store = st, tf = tf, camera = path, width = 256, height = 256, blend = "max",
                      policy = "closed_loop", target_fps = tonumber(opt["target-fps"]),
                      read_mbps = tonumber(opt["read-mbps"]), loop = true}
local run = p:run{frames = frames}
p:close()

-- Capture pass: deterministic frames at the best quality, written as PNG.
local best = info.variants[1].name
local cap = cdvr.player{store = st, tf = tf, camera = path, width = 256, height = 256, blend = "max",
                        variant = best, out = opt.out .. "/%04d.png", loop = true}
cap:run{frames = frames}
cap:close()

-- Speed against error, per variant: fps of a fixed-variant run, image PSNR of frame 1.
local ref = cdvr.render(q, {tf = tf, camera = path:camera(1, 256, 256), t = 1, blend = "max"})
print()
print(("%-8s %8s %8s %10s %10s %8s"):format("variant", "bpv", "ratio", "vol_psnr", "img_psnr", "fps"))
for _, var in ipairs(info.variants) do
  local fp = cdvr.player{store = st, tf = tf, camera = path, width = 256, height = 256, blend = "max", variant = var.name,
                         loop = true}
  local r = fp:run{frames = math.min(frames, 12)}
  fp:close()
  local img = cdvr.render(st:decode(1, var.name), {tf = tf, camera = path:camera(1, 256, 256), blend = "max"})
  local ipsnr = cdvr.compare(img, ref).psnr
  print(("%-8s %8.3f %8.4f %10.2f %10.2f %8.1f"):format(var.name, 8 * var.bytes / info.raw_bytes,
    var.bytes / info.raw_bytes, var.psnr, ipsnr, r.fps))
end

print()
print(("closed_loop policy, target %s fps, disk emulated at %s MB/s: achieved %.1f fps (median over %d frames)"):format(
  opt["target-fps"], opt["read-mbps"], run.fps, #run.frames))
for _, row in ipairs(run.frames) do
  if row.reason then
    print(("  t=%-3d %-6s %s"):format(row.t, row.variant, row.reason))
  end
end
print(("frames written to %s/0001.png .. %04d.png"):format(opt.out, frames))
st:close()
