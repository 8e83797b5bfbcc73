-- scripts/demo.lua: the README's main job, on the bundled data (share/data), no ../shared.
-- Encodes the bundled 4D ASL MRI series (64x64x24, 25 timesteps) in three variants, plays it
-- back under the closed-loop rate-control policy along an orbit camera path, writes the frames
-- to out/demo/NNNN.png, and prints the speed-against-error table. The interactive run reads
-- through an emulated slow disk (--read-mbps, default 1.5 MB/s, like a network share) so the
-- policy has to trade quality for speed.
--   build/cdvr scripts/demo.lua [--out DIR] [--frames N] [--target-fps F] [--read-mbps M]
local opt = {out = "out/demo", frames = "25", ["target-fps"] = "30", ["read-mbps"] = "1.5"}
for i = 1, #arg, 2 do opt[(arg[i] or ""):gsub("^%-%-", "")] = arg[i + 1] end

local data = cdvr.share_dir .. "/data/mpld_asl_64x64x24x25_f32.nii.gz"
local series = assert(cdvr.load(data))
local nx, ny, nz = series:dims()
local lo, hi = series:range()
local q, qinfo = series:quantize{lo = 0, hi = hi}
print(("data: %s  %dx%dx%d x %d timesteps (%s), window [0, %.1f], %d values clipped, %d NaN"):format(
  data:match("[^/]+$"), nx, ny, nz, series:timesteps(), series:type(), hi, qinfo.clipped, qinfo.nan))

os.execute(('mkdir -p "%s"'):format(opt.out))
local store_path = opt.out .. "/demo.cdv"
local st = assert(cdvr.encode(q, {variants = {{S = 1, T = 3}, {S = 4, T = 3}, {codec = "raw"}},
                                  stage2 = "lzo", path = store_path}))
local info = st:info()

-- perfusion, control points in the series' own signal units (the window is [0, hi]):
-- low signal transparent blue, mid green-yellow, high red and opaque
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {450, 0.1, 0.2, 0.6, 0}, {900, 0.2, 0.6, 1.0, 0.12},
                   {1280, 0.9, 0.9, 0.3, 0.35}, {1780, 1.0, 0.35, 0.1, 0.8}, {hi, 1, 1, 1, 1}}
local frames = tonumber(opt.frames)
-- orbit around the centre of the volume's oriented box in world (patient, mm) coordinates
local x0, x1, y0, y1, z0, z1 = st:decode(1):bounds()
local path = cdvr.path.orbit{center = {(x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2},
                             distance = 1.9 * math.max(x1 - x0, y1 - y0, z1 - z0), elevation = 30,
                             period = frames, fov = 30}
local p = cdvr.player{store = st, tf = tf, camera = path, width = 256, height = 256,
                      policy = "closed_loop", target_fps = tonumber(opt["target-fps"]),
                      read_mbps = tonumber(opt["read-mbps"]), loop = true}
local run = p:run{frames = frames}
p:close()

-- Capture pass: deterministic frames at the best quality, written as PNG.
local best = info.variants[1].name
local cap = cdvr.player{store = st, tf = tf, camera = path, width = 256, height = 256,
                        variant = best, out = opt.out .. "/%04d.png", loop = true}
cap:run{frames = frames}
cap:close()

-- Speed against error, per variant: fps of a fixed-variant run, image PSNR of frame 1.
local ref = cdvr.render(q, {tf = tf, camera = path:camera(1, 256, 256), t = 1})
print()
print(("%-8s %8s %8s %10s %10s %8s"):format("variant", "bpv", "ratio", "vol_psnr", "img_psnr", "fps"))
for _, var in ipairs(info.variants) do
  local fp = cdvr.player{store = st, tf = tf, camera = path, width = 256, height = 256, variant = var.name,
                         loop = true}
  local r = fp:run{frames = math.min(frames, 12)}
  fp:close()
  local img = cdvr.render(st:decode(1, var.name), {tf = tf, camera = path:camera(1, 256, 256)})
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
