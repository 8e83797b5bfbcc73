-- tests/lua/test_presets.lua - colour maps, presets, the automatic window, annotations and
-- JPEG stills from Lua prove:
--   * the colour maps equal their published tables: matplotlib's five 256-entry tables (read
--     from the installed matplotlib/_cm_listed.py, else the values written here, copied from
--     python3-matplotlib 3.6.3's file), ParaView's Cool to Warm against VTK 9.1's
--     vtkColorTransferFunction in its Diverging space, and ParaView's RGB-space maps at their
--     control points; opacity is the ramp or the given {x, a} points;
--   * 3D Slicer's presets keep presets.xml's points (absolute, HU) and shading settings;
--   * an unknown name lists the presets and colour maps; misused options are errors;
--   * every preset on three volumes of different types (neghip u8; with CDVR_SHARED_DATA the
--     head CT u16 and Colin27 T1 u8) renders a non-empty, non-saturated image with
--     cdvr.render's default method on the cpu device (normalised ones with range="auto"): a
--     fraction of pixels neither background nor clipped of 2% to 95% (measured 4.7% to 82%, the
--     whole box as orbit_camera frames it),
--     clipped at most 25% (measured at most 14.5%), unless the preset shows nothing of the
--     data's range, when the image is empty and one warning names the preset and the range;
--   * range="auto" rescues a normalised preset on data whose window it does not fit;
--   * img:annotate draws a colour bar and letters where asked and nothing elsewhere;
--   * img:save writes JPEG for .jpg (quality=), and refuses unknown extensions clearly.
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check, raises = checks.check, checks.raises
local tmpdir = os.getenv("CDVR_BINARY_DIR") or "."
local shared = os.getenv("CDVR_SHARED_DATA")
local function near(a, b, tol) return math.abs(a - b) <= tol end

-- ---- matplotlib -------------------------------------------------------------------------------
local MPL = "/usr/lib/python3/dist-packages/matplotlib/_cm_listed.py"
local mpl_written = { -- entries 0, 64, 128, 255 of python3-matplotlib 3.6.3's _cm_listed.py
  viridis = {{0.267004, 0.004874, 0.329415}, {0.229739, 0.322361, 0.545706},
             {0.127568, 0.566949, 0.550556}, {0.993248, 0.906157, 0.143936}},
  inferno = {{0.001462, 0.000466, 0.013866}, {0.3415, 0.062325, 0.429425},
             {0.735683, 0.215906, 0.330245}, {0.988362, 0.998364, 0.644924}},
  magma = {{0.001462, 0.000466, 0.013866}, {0.316654, 0.07169, 0.48538},
           {0.716387, 0.214982, 0.47529}, {0.987053, 0.991438, 0.749504}},
  plasma = {{0.050383, 0.029803, 0.527975}, {0.494877, 0.01199, 0.657865},
            {0.798216, 0.280197, 0.469538}, {0.940015, 0.975158, 0.131326}},
  cividis = {{0.0, 0.135112, 0.304751}, {0.263738, 0.307831, 0.422789},
             {0.488697, 0.485318, 0.471008}, {0.995737, 0.909344, 0.217772}},
}
local function mpl_table(src, name)
  local body = src:match("_" .. name .. "_data = (%b[])")
  local t = {}
  for r, g, b in body:gmatch("%[%s*([%d%.eE%-]+),%s*([%d%.eE%-]+),%s*([%d%.eE%-]+)%s*%]") do
    t[#t + 1] = {tonumber(r), tonumber(g), tonumber(b)}
  end
  return t
end
local fh = io.open(MPL, "r")
local src = fh and fh:read("a")
if fh then fh:close() end
for name, written in pairs(mpl_written) do
  local pts = cdvr.tf(name):points()
  check(#pts == 256 and cdvr.tf(name):normalized(), name .. ": 256 normalised points, got " .. #pts)
  local published = {}
  if src then
    local t = mpl_table(src, name)
    check(#t == 256, name .. ": 256 entries in " .. MPL .. ", got " .. #t)
    for i = 1, #t do published[i] = t[i] end
  else
    for k, i in ipairs{1, 65, 129, 256} do published[i] = written[k] end
  end
  for i, c in pairs(published) do
    local p = pts[i]
    check(near(p[1], (i - 1) / 255, 1e-9) and near(p[2], c[1], 1e-9) and near(p[3], c[2], 1e-9)
          and near(p[4], c[3], 1e-9) and near(p[5], (i - 1) / 255, 1e-9),
          ("%s entry %d: %g %g %g (ramp %g) against %g %g %g"):format(name, i - 1, p[2], p[3], p[4], p[5],
                                                                     c[1], c[2], c[3]))
  end
  if src then -- and the values written here are the file's
    for k, i in ipairs{1, 65, 129, 256} do
      check(near(published[i][1], written[k][1], 1e-9), name .. ": written value " .. i - 1 .. " is not the file's")
    end
  end
end

-- ---- ParaView ---------------------------------------------------------------------------------
-- Cool to Warm: vtkColorTransferFunction (VTK 9.1, SetColorSpaceToDiverging, ParaView's three
-- points) gives these; cdvr's 256 samples interpolated linearly stay within 2e-3 of them.
local ctw = cdvr.tf("cool_to_warm")
local vtk_ctw = {[0.25] = {0.5535242812881254, 0.6884073924766466, 0.9949151135935986},
                 [0.4] = {0.7537304168841361, 0.8301732236652254, 0.9609557591372208},
                 [0.5] = {0.865005711641845, 0.8650207188400469, 0.8650060758052455},
                 [0.75] = {0.958278756669391, 0.6029209175597244, 0.4817269474055517},
                 [0.9] = {0.8422077212755318, 0.3265502373379146, 0.26668592577872924}}
for x, c in pairs(vtk_ctw) do
  local r, g, b = ctw:lookup(x)
  check(near(r, c[1], 2e-3) and near(g, c[2], 2e-3) and near(b, c[3], 2e-3),
        ("cool_to_warm(%g) = %g %g %g, VTK %g %g %g"):format(x, r, g, b, c[1], c[2], c[3]))
end
local r0, g0, b0 = ctw:lookup(0)
check(near(r0, 59 / 255, 1e-4) and near(g0, 76 / 255, 1e-4) and near(b0, 192 / 255, 1e-4),
      "cool_to_warm(0) is ParaView's 59, 76, 192")
local function rgb_at(name, x, want)
  local r, g, b = cdvr.tf(name):lookup(x)
  check(near(r, want[1], 1e-6) and near(g, want[2], 1e-6) and near(b, want[3], 1e-6),
        ("%s(%g) = %g %g %g"):format(name, x, r, g, b))
end
rgb_at("black_body", 0.4, {0.901960784314, 0, 0})
rgb_at("black_body", 0.8, {0.901960784314, 0.901960784314, 0})
rgb_at("black_body", 1, {1, 1, 1})
rgb_at("xray", 0, {1, 1, 1})
rgb_at("xray", 0.25, {0.75, 0.75, 0.75})
rgb_at("grayscale", 0.5, {0.5, 0.5, 0.5})

-- opacity given separately
local o = cdvr.tf("viridis", {opacity = {{0, 0}, {0.5, 0}, {1, 0.8}}})
local vr, vg, vb = cdvr.tf("viridis"):lookup(0.75)
local r, g, b, a = o:lookup(0.75)
check(near(a, 0.4, 1e-6) and near(r, vr, 1e-6) and near(g, vg, 1e-6) and near(b, vb, 1e-6),
      "opacity points: alpha " .. a .. " at 0.75, colour unchanged")
check(select(4, o:lookup(0.3)) == 0, "opacity 0 below 0.5")
check(select(4, cdvr.tf("magma", {opacity = "ramp"}):lookup(0.3)) - 0.3 < 1e-6, "ramp")

-- ---- 3D Slicer ---------------------------------------------------------------------------------
local bone = cdvr.tf("CT-Bone")
local want = {{-3024, 0, 0, 0, 0}, {-16.4458, 0.729412, 0.254902, 0.301961, 0},
              {641.385, 0.905882, 0.815686, 0.552941, 0.715686}, {3071, 1, 1, 1, 0.705882}}
local pts = bone:points()
check(#pts == 4 and not bone:normalized() and bone:unit() == 1, "CT-Bone: 4 absolute points, unit 1 mm")
for i, w in ipairs(want) do
  for k = 1, 5 do check(near(pts[i][k], w[k], 1e-9), ("CT-Bone point %d item %d: %g"):format(i, k, pts[i][k])) end
end
local sh = bone:shade()
check(sh and sh.shade == true and sh.ambient == 0.1 and sh.diffuse == 0.9 and sh.specular == 0.2
      and sh.specular_power == 10, "CT-Bone shading from presets.xml")
local mr = cdvr.tf("MR-Default"):shade()
check(mr.ambient == 0.2 and mr.diffuse == 1 and mr.specular == 0 and mr.specular_power == 1, "MR-Default shading")
local _, _, _, amr = cdvr.tf("MR-Default"):lookup(120)
check(near(amr, 0.3, 1e-6), "MR-Default opacity 0.3 at 120")
local aaa = cdvr.tf("CT-AAA"):points() -- colour and opacity share their 6 points
check(#aaa == 6 and near(aaa[4][1], 214.389, 1e-9) and aaa[4][2] == 1 and near(aaa[4][5], 0.696078, 1e-9),
      "CT-AAA merged points")
check(cdvr.tf("hot"):shade() == nil and cdvr.tf("CT-Bone"):name() == "CT-Bone", "shade nil, name")

-- ---- names and options -------------------------------------------------------------------------
local ok, msg = pcall(cdvr.tf, "viridiss")
check(not ok and msg:find("unknown preset or colour map 'viridiss'", 1, true) and msg:find("viridis,", 1, true)
      and msg:find("CT-Bone", 1, true) and msg:find("ct_soft", 1, true) and msg:find("cool_to_warm", 1, true),
      "unknown name lists what exists: " .. tostring(msg))
raises(function() cdvr.tf("CT-Bone", {opacity = "ramp"}) end, "applies to a colour map", "opacity on a preset")
raises(function() cdvr.tf({{0, 0, 0, 0, 0}, {1, 1, 1, 1, 1}}, {opacity = "ramp"}) end, "applies to a colour map",
       "opacity on a points table")
raises(function() cdvr.tf("viridis", 5) end, "table expected", "options not a table")
raises(function() cdvr.tf("viridis", {opacity = "linear"}) end, "linear", "opacity word")
raises(function() cdvr.tf("CT-Bone", {range = "auto"}) end, "normalised", "auto on an absolute preset")
raises(function() cdvr.tf("viridis", {range = "full"}) end, '"auto"', "bad range word")
raises(function() cdvr.tf("viridis", {opacity = {{0, 2}}}) end, "must be in [0, 1]", "opacity 2")
raises(function() cdvr.tf("viridis", {opacity = 3}) end, "ramp", "opacity number")
raises(function() cdvr.tf("viridis", {percentiles = {1, 99}}) end, 'range="auto"', "percentiles alone")
raises(function() cdvr.tf("viridis", {range = "auto", percentiles = {50, 10}}) end, "lo < hi", "percentiles order")
raises(function() cdvr.tf("viridis", {opacitty = "ramp"}) end, "opacity", "misspelt option")
check(select(2, cdvr.tf("hot", {range = "auto"}):name()) == true, "auto flag")

-- ---- every preset on three volumes -------------------------------------------------------------
local function list(dir)
  local names = {}
  local p = assert(io.popen(("ls %q"):format(cdvr.share_dir .. "/" .. dir)))
  for f in p:lines() do if f:match("%.lua$") then names[#names + 1] = f:sub(1, -5) end end
  p:close()
  return names
end
local presets = list("tf")
for _, n in ipairs(list("colormaps")) do presets[#presets + 1] = n end
check(#presets >= 25, "presets and colour maps: " .. #presets)

-- fractions of pixels neither background (alpha < 1/255) nor clipped (a channel >= 254/255),
-- and clipped
local function fractions(img)
  local w, h = img:size()
  local n, nc = 0, 0
  for y = 0, h - 1 do
    for x = 0, w - 1 do
      local pr, pg, pb, pa = img:pixel(x, y)
      local clip = math.max(pr, pg, pb) >= 254 / 255
      if pa >= 1 / 255 and not clip then n = n + 1 end
      if clip then nc = nc + 1 end
    end
  end
  return n / (w * h), nc / (w * h)
end
-- 1 when the absolute TF's opacity is 0 over [lo, hi] (the warning's rule, tf.h)
local function misses(tf, lo, hi)
  if tf:normalized() then return false end
  if select(4, tf:lookup(lo)) > 0 or select(4, tf:lookup(hi)) > 0 then return false end
  for _, p in ipairs(tf:points()) do
    if p[1] >= lo and p[1] <= hi and (p[5] > 0 or select(4, tf:lookup(p[1])) > 0) then return false end
  end
  return true
end
local volumes = {{"neghip u8", cdvr.share_dir .. "/data/neghip_66x66x66_u8.nrrd"}}
if shared then
  volumes[2] = {"head CT u16", shared .. "/ct/headsq_64x64x93_u16.nrrd"}
  volumes[3] = {"Colin27 T1 u8", shared .. "/mri/colin27_t1_301x370x316_u8.nii.gz"}
else
  print("CDVR_SHARED_DATA unset: presets on the bundled neghip only")
end
local missed = {}
for _, vspec in ipairs(volumes) do
  local v = cdvr.load(vspec[2])
  local lo, hi = v:range()
  local cam = cdvr.orbit_camera(v, {width = 64, height = 64})
  for _, n in ipairs(presets) do
    local tf = cdvr.tf(n)
    if tf:normalized() then tf = cdvr.tf(n, {range = "auto"}) end
    local f, clipped = fractions(cdvr.render(v, {tf = tf, camera = cam, device = "cpu"}))
    if misses(tf, lo, hi) then
      missed[#missed + 1] = n .. " on " .. vspec[1]
      check(f == 0 and clipped == 0, ("%s on %s: shows nothing of %g..%g yet drew %.3f"):format(n, vspec[1], lo, hi, f))
    else
      check(f >= 0.02 and f <= 0.95 and clipped <= 0.25, -- at most the framed box (its corners span 90%)
            ("%s on %s: %.3f of the pixels neither background nor clipped, %.3f clipped"):format(n, vspec[1], f, clipped))
    end
  end
end
print("presets that show nothing of a volume's range: " .. table.concat(missed, ", "))
check(#missed < #presets, "most presets show something")

if shared then -- the issue's case: ct_bone on Colin27 was all black over the u8 window
  local v = cdvr.load(shared .. "/mri/colin27_t1_301x370x316_u8.nii.gz")
  local cam = cdvr.orbit_camera(v, {width = 64, height = 64})
  local plain = fractions(cdvr.render(v, {tf = "ct_bone", camera = cam, device = "cpu"}))
  local auto = fractions(cdvr.render(v, {tf = cdvr.tf("ct_bone", {range = "auto"}), camera = cam, device = "cpu"}))
  check(plain < 0.02 and auto > 0.1, ("ct_bone on Colin27: %.3f plain, %.3f with range=auto"):format(plain, auto))
end

-- range="auto" pinned now (volume=) renders like the auto TF; the player, which classifies a
-- store's frames without the voxels at hand, refuses an unpinned one and plays a pinned one
do
  local v = cdvr.load(cdvr.share_dir .. "/data/neghip_66x66x66_u8.nrrd")
  local cam = cdvr.orbit_camera(v, {width = 48, height = 48})
  local pinned = cdvr.tf("inferno", {range = "auto", volume = v})
  check(not pinned:normalized() and select(2, pinned:name()) == false, "pinned: data units")
  local a = cdvr.render(v, {tf = cdvr.tf("inferno", {range = "auto"}), camera = cam, device = "cpu"})
  local b = cdvr.render(v, {tf = pinned, camera = cam, device = "cpu"})
  check(cdvr.compare(a, b).psnr >= 60, "pinned auto TF renders like the auto one: " .. cdvr.compare(a, b).psnr)
  local st = cdvr.encode(v, {codec = "raw", path = tmpdir .. "/test_presets.cdv"})
  raises(function() cdvr.player{store = st, tf = cdvr.tf("inferno", {range = "auto"}), width = 16, height = 16} end,
         'range="auto" needs the data', "player with an unpinned auto TF")
  local p = cdvr.player{store = st, tf = pinned, width = 16, height = 16}
  check(#p:run{frames = 1}.frames == 1, "player plays the pinned TF")
  p:close()
  st:close()
  os.remove(tmpdir .. "/test_presets.cdv")
  raises(function() cdvr.tf("inferno", {volume = v}) end, 'goes with range="auto"', "volume= without auto")
end

-- the warning: one line per preset and data range, naming both
local script = tmpdir .. "/test_presets_warn.lua"
fh = assert(io.open(script, "w"))
fh:write([[
local v = cdvr.load(cdvr.share_dir .. "/data/neghip_66x66x66_u8.nrrd")
local cam = cdvr.orbit_camera(v, {width = 16, height = 16})
for _ = 1, 3 do cdvr.render(v, {tf = "CT-Lung", camera = cam, device = "cpu"}) end
cdvr.render(v, {tf = "CT-Bone", camera = cam, device = "cpu"})
print("done")
]])
fh:close()
local exe = arg and arg[-1] or "cdvr"
local p = assert(io.popen(("%q %q 2>&1"):format(exe, script)))
local out = p:read("a")
p:close()
os.remove(script)
local nwarn = select(2, out:gsub("warning", "warning"))
check(nwarn == 1 and out:find("preset 'CT-Lung'", 1, true) and out:find("0.0 .. 255.0", 1, true)
      and out:find("done", 1, true), "one warning naming the preset and the data range: " .. out)

-- ---- annotations -------------------------------------------------------------------------------
local v = cdvr.load(cdvr.share_dir .. "/data/neghip_66x66x66_u8.nrrd")
local cam = cdvr.orbit_camera(v, {width = 256, height = 256})
local tf = cdvr.tf("viridis")
local function render() return cdvr.render(v, {tf = tf, camera = cam, device = "cpu"}) end
local function changed(a, b, x0, y0, x1, y1)
  local n = 0
  for y = y0, y1 - 1 do
    for x = x0, x1 - 1 do
      local ar, ag, ab = a:pixel(x, y)
      local br, bg, bb = b:pixel(x, y)
      if ar ~= br or ag ~= bg or ab ~= bb then n = n + 1 end
    end
  end
  return n
end
local base = render()
local bar = render()
check(bar:annotate{colorbar = true, tf = tf, volume = v, unit = "density"} == bar, "annotate returns the image")
check(changed(base, bar, 150, 110, 256, 232) > 500, "colour bar drawn in the lower right")
check(changed(base, bar, 0, 0, 150, 256) == 0, "nothing drawn left of the bar")
-- the bar's colours: its top rows are viridis' top, its bottom rows viridis' bottom
local found_top, found_bottom = false, false
local tr, tg, tb = tf:lookup(1)
local br_, bg_, bb_ = tf:lookup(0)
for x = 150, 255 do
  for y = 110, 125 do
    local r_, g_, b_ = bar:pixel(x, y)
    if near(r_, tr, 0.02) and near(g_, tg, 0.02) and near(b_, tb, 0.02) then found_top = true end
  end
  for y = 218, 232 do
    local r_, g_, b_ = bar:pixel(x, y)
    if near(r_, br_, 0.02) and near(g_, bg_, 0.02) and near(b_, bb_, 0.02) then found_bottom = true end
  end
end
check(found_top and found_bottom, "bar shows the TF's top and bottom colours")
local ax = render()
ax:annotate{axes = true, camera = cam, title = "neghip", time = 1, volume = v}
check(changed(base, ax, 0, 110, 40, 146) > 10, "left letter")
check(changed(base, ax, 0, 0, 100, 24) > 20, "title top-left")
check(changed(base, ax, 0, 236, 100, 256) > 10, "time bottom-left")
check(changed(base, ax, 150, 150, 256, 232) == 0, "no colour bar when not asked")
raises(function() render():annotate{colorbar = true} end, "needs tf=", "colour bar without tf")
raises(function() render():annotate{axes = true} end, "camera", "axes without camera")
raises(function() render():annotate{axes = true, camera = cam, space = "QQQ"} end, "QQQ", "bad space")
raises(function() render():annotate{colourbar = true} end, "colorbar", "misspelt option")

-- ---- JPEG stills ---------------------------------------------------------------------------------
local jpg = tmpdir .. "/test_presets.jpg"
check(base:save(jpg, {quality = 80}) == true, "JPEG written")
fh = assert(io.open(jpg, "rb"))
local head = fh:read(3)
fh:close()
check(head == "\255\216\255", "a JPEG file (FF D8 FF)")
os.remove(jpg)
raises(function() base:save(tmpdir .. "/x.tif") end, "extension chooses the format", "unknown extension")
raises(function() base:save(tmpdir .. "/x.jpg", {alpha = true}) end, "no alpha", "alpha JPEG")
raises(function() base:save(tmpdir .. "/x.jpg", {quality = 0}) end, "1..100", "quality 0")
raises(function() base:save(tmpdir .. "/x.png", {quality = 50}) end, "applies to JPEG", "quality on PNG")

checks.finish()
