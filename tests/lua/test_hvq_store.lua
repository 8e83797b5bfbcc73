-- The hvq codec through the store, the renderers and the player (issue 13 item 3): encode
-- with grad/residual, st:info() parts and counts, st:decode within `residual` of the input;
-- cdvr.render(st, {device="cl"}) renders in the compressed domain (device memory = compressed
-- payload + the parameter blob, far below the dense volume) and matches the CPU render of the
-- C-decoded volume (>= 50 dB); the player plays the hvq variant on both devices.
local tmp = os.tmpname()
os.remove(tmp)
assert(os.execute(("mkdir -p %q"):format(tmp)))
-- a sparse blob field: mostly zero, smooth structure, sharp edges (residual voxels)
local vol = cdvr.generate("sphere", {dims = {40, 36, 30}, timesteps = 3, radius = 0.5})
for t = 1, 3 do
  for z = 10, 14 do for y = 5, 8 do for x = 30, 35 do vol:set(x, y, z, t, 37 * t + x) end end end
end
local st = assert(cdvr.encode(vol, {path = tmp .. "/h.cdv", progress = false, variants = {
  {codec = "hvq", grad = 64, residual = 10, name = "hvq"}, {codec = "hvq", name = "hvq8"},
  {S = 1, T = 3}}}))
local info = st:info()
local h = info.variants[1]
assert(h.codec == "hvq" and h.grad == 64 and h.residual == 10, "parameters listed")
for _, part in ipairs{"means", "codebook1", "codebook2", "index_hash", "residual_hash"} do
  assert(type(h[part]) == "number" and h[part] >= 0, "part bytes: " .. part)
end
assert(h.header + h.means + h.codebook1 + h.codebook2 + h.index_hash + h.residual_hash ==
       h.payload_bytes, "parts add up to the payload")
assert(h.zero_blocks > 0 and h.residual_voxels > 0 and h.ratio < 1, "counts and ratio (stored / raw)")
local dense = 40 * 36 * 30
assert(h.device_bytes < dense / 2, ("hvq device bytes %d of %d dense"):format(h.device_bytes, dense))
assert(info.variants[3].device_bytes == 3 * dense, "PVTC holds a chunk's dense frames")
assert(h.maxerr <= 10, "every voxel within residual: " .. h.maxerr)
for t = 1, 3 do
  local d = st:decode(t, "hvq")
  assert(cdvr.compare(d, vol:frame(t)).maxerr <= 10)
end

local tf = cdvr.tf{{0, 0, 0, 0, 0}, {60, 1, .6, .2, .2}, {255, 1, 1, 1, .9}}
local cam = cdvr.orbit_camera(vol, {azimuth = 40, elevation = 25, width = 64, height = 56})
if cdvr.cl_info() then
  for _, name in ipairs{"hvq", "hvq8"} do
    for t = 1, 3 do
      local o = {t = t, variant = name, tf = tf, camera = cam, device = "cl", fetch = "sample"}
      local img, stats = cdvr.render(st, o)
      local ref = cdvr.render(st:decode(t, name), {tf = tf, camera = cam, device = "cpu"})
      local c = cdvr.compare(img, ref)
      assert(c.psnr >= 50, ("%s t=%d: compressed-domain render %.2f dB"):format(name, t, c.psnr))
      assert(stats.volume_bytes < dense / 2 and stats.volume_bytes > 48,
             "the device holds the compressed payload: " .. stats.volume_bytes)
      -- the bulk path (C decoder, dense render) and auto give the very same image
      for _, path in ipairs{"bulk", "auto"} do
        o.fetch = path
        local img2, stats2 = cdvr.render(st, o)
        local c2 = cdvr.compare(img2, img)
        assert(c2.maxerr == 0, ("%s t=%d fetch=%s: differs from the fetch by %g"):format(
               name, t, path, c2.maxerr))
        if path == "bulk" then
          assert(stats2.volume_bytes >= dense and stats2.volume_bytes % dense == 0, "bulk holds dense frames: " ..
                 stats2.volume_bytes)
        end
      end
    end
  end
  local ok, err = pcall(cdvr.render, st, {variant = "hvq", tf = tf, camera = cam, device = "cl",
                                          fetch = "fast"})
  assert(not ok and err:find("fetch"), "bad fetch= is an error: " .. tostring(err))
end

local devices = {"cpu"}
if cdvr.cl_info() then devices[2] = "cl" end
local runs = {{"cpu"}}
if cdvr.cl_info() then runs = {{"cpu"}, {"cl", "sample"}, {"cl", "bulk"}, {"cl", "auto"}} end
local function slurp(path)
  local f = assert(io.open(path, "rb"))
  local s = f:read("a")
  f:close()
  return s
end
for _, run in ipairs(runs) do
  local dev, path = run[1], run[2]
  local out = ("%s/%s_%s_%%d.png"):format(tmp, dev, path or "")
  local p = cdvr.player{store = st, tf = tf, camera = cam, device = dev, variant = "hvq",
                        fetch = path, out = out}
  local r = p:run{frames = 3}
  for _, row in ipairs(r.frames) do
    assert(not row.error, row.error)
    if path == "sample" then
      assert(row.device_bytes > 0 and row.device_bytes < dense + 4 * 64 * 56 * 4 + 65536,
             "player device bytes " .. row.device_bytes)
    end
  end
  p:close()
  if dev == "cl" and path ~= "sample" then -- every path plays the same images
    for i = 1, 3 do
      assert(slurp(out:format(i)) == slurp((tmp .. "/cl_sample_%d.png"):format(i)),
             ("player fetch=%s frame %d differs from the fetch"):format(path, i))
    end
  end
end
local ok, err = pcall(cdvr.player, {store = st, tf = tf, camera = cam, fetch = "fast"})
assert(not ok and err:find("fetch"), "bad player fetch= is an error: " .. tostring(err))
os.execute(("rm -rf %q"):format(tmp))
print("test_hvq_store: ok")
