-- tests/lua/test_tf_units.lua - transfer functions in data units (tf.h, volume.h value window):
-- a TF written in the data's own units classifies float, 16-bit and quantized volumes alike;
-- a series has one window for every frame (render(v, {t=2}) == render(v:frame(2))); presets
-- are normalised and follow the data's window unless pinned with range=; a store records the
-- quantize window and its decoded frames classify like the quantized series. Real files of
-- ../shared/data (combustor float, headsq u16, viscous fingers) when CDVR_SHARED_DATA is set;
-- the bundled ASL series always.
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check = checks.check
local function psnr(a, b) return cdvr.compare(a, b).psnr end
local function same(a, b, what) check(psnr(a, b) == math.huge, what .. ": images differ (" .. psnr(a, b) .. " dB)") end
local tmpdir = os.getenv("CDVR_BINARY_DIR") or "."
local data = os.getenv("CDVR_SHARED_DATA")
local W = 64

-- An 8-bit copy of q whose window is [0, 255] (codes are values), as a u8 file would load.
local function as_codes(q)
  local nx, ny, nz = q:dims()
  local c = cdvr.volume{dims = {nx, ny, nz}, spacing = {q:spacing()}}
  for z = 0, nz - 1 do for y = 0, ny - 1 do for x = 0, nx - 1 do c:set(x, y, z, q:get(x, y, z)) end end end
  return c
end

-- Mean alpha over the pixels where `cover` is opaque (the box's silhouette).
local function coverage(img, cover)
  local w, h = img:size()
  local n, opaque = 0, 0
  for y = 0, h - 1 do
    for x = 0, w - 1 do
      if select(4, cover:pixel(x, y)) > 0.5 then
        n = n + 1
        if select(4, img:pixel(x, y)) > 0.95 then opaque = opaque + 1 end
      end
    end
  end
  return opaque / math.max(n, 1), n
end

-- the bundled ASL series (float, signed): one window for the series
local asl = assert(cdvr.load(cdvr.share_dir .. "/data/mpld_asl_64x64x24x25_f32.nii.gz"))
local alo, ahi = asl:range()
local wlo, whi = asl:window()
check(wlo == alo and whi == ahi, "series window = range over all timesteps")
local f2 = asl:frame(2)
local flo, fhi = f2:window()
check(flo == alo and fhi == ahi, "frame(2) keeps the series window, not its own range " .. flo .. " " .. fhi)
local asl_tf = cdvr.tf{{0, 0, 0, 0, 0}, {150, 0.2, 0.4, 1, 0.05}, {400, 1, 0.6, 0.1, 0.6}, {ahi, 1, 1, 1, 1}}
local acam = cdvr.orbit_camera(asl, {azimuth = 30, elevation = 20, width = W, height = W})
for _, t in ipairs{2, 17} do
  same(cdvr.render(asl, {tf = asl_tf, camera = acam, t = t}), cdvr.render(asl:frame(t), {tf = asl_tf, camera = acam}),
       "ASL render(v, {t=" .. t .. "}) vs render(v:frame(" .. t .. "))")
end
-- a quantized copy over the same window classifies the same data values the same way
local aq = asl:quantize{lo = alo, hi = ahi}
check(select(1, aq:window()) == alo and select(2, aq:window()) == ahi, "quantize output carries its window")
same(cdvr.render(asl, {tf = asl_tf, camera = acam, t = 3}), cdvr.render(aq, {tf = asl_tf, camera = acam, t = 3}),
     "ASL float vs quantized over the same window")
-- v:set on a float series resets the cached window
local small = cdvr.volume{dims = {4, 4, 4}, type = "f32"}
check(select(2, small:window()) == 0, "zero volume window")
small:set(1, 1, 1, 9.5)
check(select(2, small:window()) == 9.5, "window follows v:set")

-- stores record the quantize window; decoded frames classify like the quantized series
local ml = cdvr.generate("ml", {dims = {24, 20, 16}, timesteps = 3, type = "f32"})
local mlo, mhi = ml:range()
local q = ml:quantize{lo = mlo, hi = mlo + 0.6 * (mhi - mlo)}
local qlo, qhi = q:window()
local spath = tmpdir .. "/test_tf_units.cdv"
local st = assert(cdvr.encode(q, {variants = {{codec = "raw"}}, path = spath, progress = false}))
local info = st:info()
check(info.window[1] == qlo and info.window[2] == qhi, "store records the quantize window: " ..
      info.window[1] .. " " .. info.window[2])
local d2 = st:decode(2)
check(select(1, d2:window()) == qlo and select(2, d2:window()) == qhi, "decoded frame carries the store window")
local ml_tf = cdvr.tf{{mlo, 0, 0, 0, 0}, {(mlo + mhi) / 2, 0.2, 0.4, 1, 0.1}, {qhi, 1, 1, 1, 0.8}}
local mcam = cdvr.orbit_camera(ml, {azimuth = 30, elevation = 20, width = W, height = W})
same(cdvr.render(d2, {tf = ml_tf, camera = mcam}), cdvr.render(q, {tf = ml_tf, camera = mcam, t = 2}),
     "store frame vs quantized series")
-- the player classifies over the store window too: its frame is cdvr.render's, byte for byte
local pcam = cdvr.orbit_camera(ml, {azimuth = 30, elevation = 20, width = 40, height = 40})
local player = cdvr.player{store = st, tf = ml_tf, camera = pcam, device = "cpu",
                           out = tmpdir .. "/test_tf_units_%d.png"}
player:run{frames = 2}
player:close()
cdvr.render(st:decode(2), {tf = ml_tf, camera = pcam, device = "cpu"}):save(tmpdir .. "/test_tf_units_ref.png")
local function bytes(path)
  local f = assert(io.open(path, "rb"))
  local b = f:read("a")
  f:close()
  os.remove(path)
  return b
end
check(bytes(tmpdir .. "/test_tf_units_2.png") == bytes(tmpdir .. "/test_tf_units_ref.png"),
      "player frame 2 = cdvr.render(st:decode(2)) with a TF in data units")
os.remove(tmpdir .. "/test_tf_units_1.png")
st:close()
local st2 = assert(cdvr.open(spath))
check(st2:info().window[2] == qhi, "window read back from the file")
st2:close()
os.remove(spath)

if not data then
  print("CDVR_SHARED_DATA not set: real-data part skipped")
else
  -- combustor: float density 0.198 .. 0.710, a TF in its own units
  local comb = assert(cdvr.load(data .. "/sim/combustor_density_57x33x25_f32.nrrd"))
  local lo, hi = comb:range()
  local tf = cdvr.tf{{0.2, 0, 0, 0, 0}, {0.45, 0.2, 0.4, 1, 0.0}, {0.6, 1, 0.6, 0.1, 0.3}, {0.7, 1, 1, 1, 0.9}}
  local cam = cdvr.orbit_camera(comb, {azimuth = 30, elevation = 25, width = W, height = W})
  local img = cdvr.render(comb, {tf = tf, camera = cam})
  local solid = cdvr.render(comb, {tf = cdvr.tf{{0, 1, 1, 1, 1}}, camera = cam})
  local frac, silhouette = coverage(img, solid)
  check(silhouette > 500 and frac < 0.5, ("combustor is not a solid box: %.2f of %d silhouette pixels opaque"):format(frac, silhouette))
  -- the same TF on the quantized volume, and converted to codes on a plain 8-bit copy
  local cq = comb:quantize{lo = lo, hi = hi}
  same(img, cdvr.render(cq, {tf = tf, camera = cam}), "combustor float vs quantized")
  local pts = {}
  for i, p in ipairs(tf:points()) do pts[i] = {(p[1] - lo) * 255 / (hi - lo), p[2], p[3], p[4], p[5]} end
  pts[1][1] = math.max(pts[1][1], 0)
  local coded = cdvr.render(as_codes(cq), {tf = cdvr.tf(pts), camera = cam})
  check(psnr(img, coded) > 80, "data units = the same TF written in codes: " .. psnr(img, coded) .. " dB")

  -- headsq: u16 CT values 0 .. 3926
  local head = assert(cdvr.load(data .. "/ct/headsq_64x64x93_u16.nrrd"))
  local hlo, hhi = head:window()
  check(hlo == 0 and hhi == 3926, "headsq window " .. hlo .. " " .. hhi)
  local hcam = cdvr.orbit_camera(head, {azimuth = 90, elevation = 10, width = W, height = W})
  local ct = cdvr.tf{{0, 0, 0, 0, 0}, {500, 0.6, 0.3, 0.2, 0}, {1000, 0.9, 0.6, 0.5, 0.05}, {1200, 1, 0.9, 0.8, 0.6}}
  local himg = cdvr.render(head, {tf = ct, camera = hcam})
  same(himg, cdvr.render(head:quantize{lo = hlo, hi = hhi}, {tf = ct, camera = hcam}), "headsq CT values: u16 vs quantized")
  check(coverage(himg, cdvr.render(head, {tf = cdvr.tf{{0, 1, 1, 1, 1}}, camera = hcam})) > 0.2, "headsq skin visible")
  -- presets follow the window unless pinned
  local bone = cdvr.render(head, {tf = "ct_bone", camera = hcam})
  same(bone, cdvr.render(head, {tf = cdvr.tf("ct_bone", {range = {hlo, hhi}}), camera = hcam}),
       "normalised preset = preset pinned to the data's window")
  local pinned = cdvr.render(head, {tf = cdvr.tf("ct_bone", {range = {0, 2000}}), camera = hcam})
  check(psnr(bone, pinned) < 30, "pinning ct_bone to [0, 2000] changes the picture")

  -- viscous fingers: a float series, one window for every frame
  local vf = assert(cdvr.load_series(data .. "/series/viscousfingers/vf_t%03d.nrrd", {first = 40, count = 5}))
  local vcam = cdvr.orbit_camera(vf, {azimuth = 30, elevation = 20, width = W, height = W})
  local hot = cdvr.tf("hot")
  for t = 2, 5, 3 do
    same(cdvr.render(vf, {tf = hot, camera = vcam, t = t}), cdvr.render(vf:frame(t), {tf = hot, camera = vcam}),
         "viscous fingers render(v, {t=" .. t .. "}) vs render(v:frame(" .. t .. "))")
  end
end

checks.finish()
