-- tests/lua/test_splat.lua - the Lua surface of splatting: cdvr.splat_order (#o, o[i],
-- thresholds, perspective), cdvr.splat_order_quality, cdvr.render{method="splat"}; misuse
-- raises naming the function and the reason, unknown option keys are rejected.
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check, raises = checks.check, checks.raises

-- orders: a permutation of 0..N-1, back to front
local dims = {5, 3, 7}
for _, how in ipairs{"dda", "axis", "sort", "quicksort"} do
  local o = cdvr.splat_order(dims, {0.3, -1, 0.5}, how)
  check(#o == 105, how .. ": #o = " .. #o)
  local seen, ok = {}, true
  for i = 1, #o do
    local v = o[i]
    ok = ok and math.type(v) == "integer" and v >= 0 and v < 105 and not seen[v]
    seen[v] = true
  end
  check(ok, how .. ": o[i] lists every voxel once")
  check(o[0] == nil and o[106] == nil and o[1.5] == nil, how .. ": outside 1..#o is nil")
  check(tostring(o):find("cdvr.SplatOrder 105 voxels of 5x3x7", 1, true), tostring(o))
  local x, y, z = o:dims()
  check(x == 5 and y == 3 and z == 7, "o:dims()")
end
-- along +x the far sheet is x = 4: the first voxel drawn has x = 4, the last x = 0
local o = cdvr.splat_order(dims, {1, 0, 0}, "dda")
check(o[1] % 5 == 4 and o[#o] % 5 == 0, "along +x: far sheet first")
-- exactly diagonal: far corner first
o = cdvr.splat_order(dims, {-1, -1, -1}, "dda")
check(o[1] == 0 and o[#o] == 104, "diagonal: corners " .. o[1] .. " " .. o[#o])
-- sort and quicksort agree
local s, q = cdvr.splat_order({9, 8, 7}, {0.2, 0.7, -0.4}, "sort"), cdvr.splat_order({9, 8, 7}, {0.2, 0.7, -0.4}, "quicksort")
local same = #s == #q
for i = 1, #s do same = same and s[i] == q[i] end
check(same, "radix sort and quicksort give the same order")
-- perspective from an eye inside
o = cdvr.splat_order(dims, {eye = {2, 1, 3}}, "dda")
check(#o == 105, "perspective: all voxels")
local so = cdvr.splat_order(dims, {eye = {2, 1, 3}}, "sort")
local last = so[#so]
check(last == 2 + 5 * (1 + 3 * 3), "perspective sort ends at the eye's voxel: " .. last)

-- thresholds on a u8 volume and on a float volume (the seed's fill ratio)
local v = cdvr.generate("ramp", {dims = {8, 4, 3}})
local above = 0
for z = 0, 2 do for y = 0, 3 do for x = 0, 7 do
  if v:get(x, y, z) > 100 then above = above + 1 end
end end end
o = cdvr.splat_order({8, 4, 3}, {1, 0.2, 0.1}, "dda", {threshold = 100, volume = v})
check(#o == above and above > 0 and above < 96, "threshold lists " .. #o .. " of " .. above)
for i = 1, #o do
  local lin = o[i]
  check(v:get(lin % 8, (lin // 8) % 4, lin // 32) > 100, "listed voxel above the threshold")
end
local f = cdvr.generate("ramp", {dims = {8, 4, 3}, type = "f32"})
local lo, hi = f:range()
local of = cdvr.splat_order({8, 4, 3}, {1, 0.2, 0.1}, "sort", {threshold = (lo + hi) / 2, volume = f})
check(#of > 0 and #of < 96, "float volume threshold in data units: " .. #of)
do
  local closed <close> = cdvr.splat_order({2, 2, 2}, {1, 1, 1}, "axis")
  o = closed
end
raises(function() return #o end, "closed splat order", "use after close")

-- argument errors
raises(function() cdvr.splat_order({5, 3}, {1, 0, 0}, "dda") end, "dims must be {X, Y, Z}", "two dims")
raises(function() cdvr.splat_order({5, 0, 3}, {1, 0, 0}, "dda") end, "dims must be integers >= 1", "zero dim")
raises(function() cdvr.splat_order({5, 3, 2.5}, {1, 0, 0}, "dda") end, "integers", "fractional dim")
raises(function() cdvr.splat_order(dims, {0, 0, 0}, "dda") end, "must not be zero", "zero direction")
raises(function() cdvr.splat_order(dims, {1, 0 / 0, 0}, "dda") end, "finite", "NaN direction")
raises(function() cdvr.splat_order(dims, {1, 0, 0}, "bubble") end, "invalid option 'bubble'", "unknown how")
raises(function() cdvr.splat_order(dims, {1, 0, 0}, "dda", {treshold = 3}) end,
       "unknown option 'treshold' (did you mean 'threshold'?)", "misspelt option")
raises(function() cdvr.splat_order(dims, {1, 0, 0}, "dda", {threshold = 3}) end,
       "'threshold' and 'volume' go together", "threshold without volume")
raises(function() cdvr.splat_order(dims, {1, 0, 0}, "dda", {t = 1}) end,
       "'threshold' and 'volume' go together", "t without volume")
raises(function() cdvr.splat_order(dims, {1, 0, 0}, "dda", {threshold = 3, volume = v}) end,
       "volume is 8x4x3", "volume of other dims")
raises(function() cdvr.splat_order({8, 4, 3}, {1, 0, 0}, "dda", {threshold = 3, volume = v, t = 2}) end,
       "t = 2 outside 1..1", "t out of range")
raises(function() cdvr.splat_order(dims, {eye = {1, 2}}, "dda") end, "3 finite numbers", "short eye")
raises(function() cdvr.splat_order(dims, {1, 2, 3, eye = {1, 2, 3}}, "dda") end, "not both", "both")
raises(function() cdvr.splat_order({65536, 65536, 2}, {1, 0, 0}, "dda") end, "2^32", "too many voxels")

-- quality: the DDA is far better than the axis order near 45 degrees
local d45 = {math.cos(math.rad(44)), math.sin(math.rad(44)), 0}
local fa, sa = cdvr.splat_order_quality({40, 30, 20}, d45, "axis")
local fd, sd = cdvr.splat_order_quality({40, 30, 20}, d45, "dda")
check(fa > 0.005 and fd < fa / 10, string.format("wrong pairs axis %g dda %g", fa, fd))
check(sa.pairs > 0 and sa.pairs == sd.pairs and sa.offsets > 0 and sa.sampled == false,
      "quality stats: pairs " .. sa.pairs)
check(sd.max_inversion <= 2 * math.sin(math.rad(44)) + 1e-9, "dda worst inversion " .. sd.max_inversion)
local fs = cdvr.splat_order_quality({40, 30, 20}, d45, cdvr.splat_order({40, 30, 20}, d45, "sort"))
check(fs == 0, "an order object: the sort has no wrong pair")
local _, small = cdvr.splat_order_quality({40, 30, 20}, d45, "dda", {budget = 5000, radius = 1})
check(small.sampled == true, "small budget samples")
raises(function() cdvr.splat_order_quality({4, 4, 4}, {eye = {1, 1, 1}}, "dda") end,
       "no perspective", "quality with an eye")
raises(function() cdvr.splat_order_quality({4, 4, 4}, {1, 0, 0}, "dda", {raduis = 1}) end,
       "did you mean 'radius'", "misspelt quality option")
raises(function() cdvr.splat_order_quality({4, 4, 4}, {1, 0, 0}, cdvr.splat_order({4, 4, 5}, {1, 0, 0}, "dda")) end,
       "the order is for 4x4x5", "order of other dims")

-- rendering
local blob = cdvr.generate("sphere", {dims = {24, 24, 24}, radius = 0.6})
local tf = cdvr.tf{ {0, 0, 0, 0, 0}, {255, 1, 0.8, 0.6, 0.6} }
local cam = cdvr.orbit_camera(blob, {azimuth = 30, elevation = 20, width = 48, height = 40})
local img, st = cdvr.render(blob, {method = "splat", tf = tf, camera = cam})
local w, h = img:size()
check(w == 48 and h == 40, "image size")
check(st.splats > 0 and st.fragments > 0 and st.ms >= 0 and st.order_ms >= 0, "stats")
local r, g, b, a = img:pixel(24, 20)
check(a > 0.5 and r <= a + 1e-6, "centre pixel drawn, premultiplied: " .. a)
for _, how in ipairs{"axis", "sort", "quicksort"} do
  local other = cdvr.render(blob, {method = "splat", order = how, tf = tf, camera = cam})
  local cmp = cdvr.compare(img, other)
  check(cmp.psnr > 40, how .. " close to dda on a sphere: " .. cmp.psnr)
end
local _, st2 = cdvr.render(blob, {method = "splat", tf = tf, camera = cam, threshold = 255})
check(st2.splats == 0, "threshold 255: no splats")
local _, st3 = cdvr.render(blob, {method = "splat", tf = tf, camera = cam, radius = 1.2, sigma = 0.5, threads = 1})
check(st3.fragments < st.fragments, "smaller radius, fewer fragments")
local ref = cdvr.render(blob, {tf = tf, camera = cam})
-- a hard-edged sphere: splats blur the silhouette the ray caster keeps sharp (measured 22.4 dB)
check(cdvr.compare(ref, img).psnr > 18, "splat vs ray cast on a sphere: " .. cdvr.compare(ref, img).psnr)
local fimg = cdvr.render(cdvr.generate("sphere", {dims = {12, 12, 12}, type = "f32"}),
                         {method = "splat", tf = tf})
check(fimg:size() > 0, "float volumes are quantized first")
-- a store renders through the CPU decode, the same as its volume
local store_path = (os.getenv("CDVR_BINARY_DIR") or ".") .. "/test_splat_store.cdv"
local series = cdvr.generate("sphere", {dims = {13, 11, 9}, timesteps = 2})
local st_raw = assert(cdvr.encode(series, {path = store_path, progress = false,
                                           variants = {{codec = "raw"}}}))
local scam = cdvr.orbit_camera(series, {azimuth = 50, elevation = 30, width = 32, height = 32})
local from_store = cdvr.render(st_raw, {method = "splat", tf = tf, camera = scam, t = 2, variant = "raw"})
local from_volume = cdvr.render(series, {method = "splat", tf = tf, camera = scam, t = 2})
check(cdvr.compare(from_store, from_volume).psnr == math.huge, "store and volume give the same splat image")
raises(function() cdvr.render(st_raw, {method = "splat", tf = tf, device = "cl"}) end, "renders on cpu, not cl",
       "store splat on OpenCL")
st_raw:close()
os.remove(store_path)
raises(function() cdvr.render(blob, {method = "splat", tf = tf, step = 0.5}) end,
       "unknown option 'step'", "ray-casting option with splat")
raises(function() cdvr.render(blob, {method = "splat", tf = tf, radus = 1}) end,
       "did you mean 'radius'", "misspelt splat option")
raises(function() cdvr.render(blob, {method = "splat", tf = tf, order = "bubble"}) end,
       "invalid value 'bubble'", "unknown order")
raises(function() cdvr.render(blob, {method = "splat", tf = tf, radius = 0}) end,
       "must be > 0", "zero radius")
raises(function() cdvr.render(blob, {method = "splat", tf = tf, sigma = -1}) end,
       "must be > 0", "negative sigma")
raises(function() cdvr.render(blob, {method = "splat", tf = tf, radius = 40}) end,
       "radius", "radius too large")
raises(function() cdvr.render(blob, {method = "splat", tf = tf, device = "cl"}) end,
       "renders on cpu, not cl", "splat on OpenCL")
raises(function() cdvr.render(blob, {method = "splat", tf = tf, threshold = "high"}) end,
       "number expected", "threshold of the wrong type")

checks.finish()
