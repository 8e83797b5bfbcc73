-- tests/lua/test_render.lua - the Lua surface of transfer functions, cameras, cdvr.render,
-- images and cdvr.compare; misuse raises, I/O failures return nil, msg.
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check, raises = checks.check, checks.raises
local function near(a, b, tol) return math.abs(a - b) <= (tol or 1e-6) end
local tmpdir = os.getenv("CDVR_BINARY_DIR") or "."

-- transfer functions
local tf = cdvr.tf{ {255, 1, 1, 1, 1}, {0, 0, 0, 0, 0}, unit = 2 }
check(tostring(tf):find("cdvr.TF", 1, true), "tostring " .. tostring(tf))
local r, g, b, a = tf:lookup(127.5)
check(near(r, 0.5) and near(a, 0.5), "lookup 127.5: " .. r .. " " .. a)
check(select(4, tf:lookup(-5)) == 0 and near(select(4, tf:lookup(999)), 1), "lookup clamps")
local pts = tf:points()
check(#pts == 2 and pts[1][1] == 0 and pts[2][1] == 255 and pts.unit == 2, "points sorted, unit")
local path = tmpdir .. "/test_render_tf.lua"
check(tf:save(path) == true, "tf:save")
local back = cdvr.tf(dofile(path))
check(back:unit() == 2 and #back:points() == 2 and select(4, back:lookup(51)) == select(4, tf:lookup(51)),
      "saved TF reads back through dofile")
check(cdvr.tf(path):points()[2][2] == 1, "cdvr.tf(path.lua)")
os.remove(path)
local nilv, msg = tf:save("/nonexistent-dir/tf.lua")
check(nilv == nil and type(msg) == "string" and msg:find("nonexistent", 1, true), "save to bad path: " .. tostring(msg))
local ok
ok, msg = pcall(cdvr.tf, "/nonexistent-dir/tf.lua")
check(not ok and tostring(msg):find("/nonexistent-dir/tf.lua", 1, true) and tostring(msg):find("cannot open", 1, true),
      "load of a missing TF file raises, naming the file and the reason: " .. tostring(msg))
local badtf = os.tmpname() .. ".lua"
local bf = assert(io.open(badtf, "w")); bf:write("return {{0, 0,0,0, 0},"); bf:close()
ok, msg = pcall(cdvr.tf, badtf)
check(not ok and tostring(msg):find(badtf, 1, true), "a malformed TF file raises, naming it: " .. tostring(msg))
os.remove(badtf)
for _, name in ipairs{"grayscale", "ct_bone", "ct_soft", "hot", "mri"} do
  local p = cdvr.tf(name)
  check(p and #p:points() >= 2, "preset " .. name)
end
local bone = cdvr.tf("ct_bone")
check(bone:normalized() and select(4, bone:lookup(250 / 255)) > 0.8 and select(4, bone:lookup(60 / 255)) == 0,
      "ct_bone: normalised, dense opaque, air clear")
local bone_hu = cdvr.tf("ct_bone", {range = {-1000, 3000}})
check(not bone_hu:normalized() and select(4, bone_hu:lookup(2800)) > 0.8 and select(4, bone_hu:lookup(0)) == 0,
      "ct_bone pinned to [-1000, 3000]")
check(bone_hu:points()[2][1] == -1000 + 4000 * 120 / 255, "pinned point value")
raises(function() cdvr.tf({{0, 0, 0, 0, 0}}, {range = {0, 1}}) end, "normalised", "range on a TF in data units")
raises(function() cdvr.tf("hot", {range = {5, 1}}) end, "lo <= hi", "inverted range")
local saved = tmpdir .. "/test_render_bone.lua"
check(bone:save(saved) == true and cdvr.tf(saved):normalized(), "a normalised TF saves as normalised")
os.remove(saved)
raises(function() cdvr.tf("no_such_preset") end, "unknown preset", "unknown preset")
raises(function() cdvr.tf("../../etc/passwd") end, "bad preset name", "preset path traversal")
raises(function() cdvr.tf{} end, "control points", "empty TF")
raises(function() cdvr.tf{ {0, 0, 0, 0} } end, "5 numbers", "short point")
check(cdvr.tf{ {1000, 0, 0, 0, 0}, {3000, 1, 1, 1, 1} }, "values in data units (CT) are accepted")
raises(function() cdvr.tf{ {1.5, 0, 0, 0, 0}, normalized = true } end, "1.5", "normalised value out of range")
raises(function() cdvr.tf{ {0, 0, 0, 0, 2} } end, "[0, 1]", "alpha out of range")
raises(function() cdvr.tf(42) end, nil, "number argument")
raises(function() tf:lookup("x") end, nil, "lookup of a string")

-- cameras
local cam = cdvr.camera{eye = {0, -10, 0}, center = {0, 0, 0}, width = 64, height = 32, fov = 45}
check(cam.width == 64 and cam.height == 32 and cam.fov == 45 and cam.eye[2] == -10, "camera fields")
local t = cam:get()
check(t.up[3] == 1 and t.center[1] == 0 and t.orthographic == false, "cam:get defaults")
cam:set{fov = 60}
check(cam.fov == 60, "cam:set")
raises(function() cam:set{fov = 0} end, "fov", "set invalid fov")
check(cam.fov == 60, "camera unchanged after a failed set")
raises(function() cdvr.camera{center = {0, 0, 0}} end, "eye", "camera without eye")
raises(function() cdvr.camera{eye = {0, 0, 5}} end, "parallel", "up parallel to view")
raises(function() cdvr.camera{eye = {0, 0, 0}, center = {0, 0, 0}} end, "eye equals center", "eye == center")
raises(function() cdvr.camera{eye = {1, 2}} end, "3 numbers", "short eye")
raises(function() cdvr.camera{eye = {0, -1, 0}, width = 0} end, "width", "zero width")
raises(function() cdvr.camera{eye = {0, -1, 0}, orthographic = true} end, "ortho_height", "ortho without height")
check(tostring(cam):find("cdvr.Camera", 1, true), "camera tostring")
local campath = tmpdir .. "/test_render_cam.lua"
check(cam:save(campath) == true, "cam:save")
local cam2 = cdvr.camera(campath)
check(cam2.fov == 60 and cam2.width == 64 and cam2.eye[2] == -10, "camera reads back from its file")
check(cdvr.camera(dofile(campath)).height == 32, "cdvr.camera(dofile(path))")
os.remove(campath)
nilv, msg = cam:save("/nonexistent-dir/cam.lua")
check(nilv == nil and msg:find("nonexistent", 1, true), "cam:save to a bad path: " .. tostring(msg))
local okc, cmsg = pcall(cdvr.camera, "/nonexistent-dir/cam.lua")
check(not okc and tostring(cmsg):find("/nonexistent-dir/cam.lua", 1, true) and tostring(cmsg):find("cannot open", 1, true),
      "cdvr.camera of a missing file raises, naming the file and the reason: " .. tostring(cmsg))

local orbit = cdvr.orbit_camera({17, 17, 17}, {azimuth = 90, elevation = 0, width = 33, height = 33})
check(near(orbit.center[1], 8) and near(orbit.center[3], 8) and orbit.eye[2] > 8 and near(orbit.eye[1], 8, 1e-9),
      "orbit azimuth 90 puts the eye on +y")
local dist = orbit.eye[2] - 8
-- the nearest face's corners (8 off the axis, dist - 8 ahead) at 90% of the half view
check(near(dist, 8 + 8 / (0.9 * math.tan(math.rad(15))), 1e-6), "default distance frames the box at 90%: " .. dist)
local zoomed = cdvr.orbit_camera({17, 17, 17}, {azimuth = 90, elevation = 0, width = 33, height = 33, zoom = 2})
check(near(zoomed.eye[2] - 8, dist / 2, 1e-9), "zoom=2 halves the distance")
raises(function() cdvr.orbit_camera({17, 17}) end, nil, "orbit with 2 dims")
raises(function() cdvr.orbit_camera({4, 4, 4}, {elevation = 90}) end, "parallel", "orbit looking along up")

-- rendering a constant box: 1 - A = (1 - a)^(L / unit) along the centre ray (L = 16)
local box = cdvr.volume{dims = {17, 17, 17}}
for z = 0, 16 do for y = 0, 16 do for x = 0, 16 do box:set(x, y, z, 100) end end end
local white = cdvr.tf{ {100, 1, 1, 1, 0.3}, unit = 10 }
local img, stats = cdvr.render(box, {tf = white, camera = orbit, step = 0.37, term = 2})
check(getmetatable(img).__name == "cdvr.Image", "render returns a cdvr.Image")
check(type(stats) == "table" and stats.samples > 0 and stats.ms >= 0, "render stats")
local w, h = img:size()
check(w == 33 and h == 33, "image size")
local pr, pg, pb, pa = img:pixel(16, 16)
check(near(1 - pa, 0.7 ^ (16 / 10), 1e-3) and near(pr, pa, 1e-6), "analytic centre pixel: " .. pa)
check(select(4, img:pixel(0, 0)) == 0, "corner pixel misses the box")
raises(function() img:pixel(33, 0) end, "outside", "pixel out of range")
raises(function() img:pixel(0, -1) end, "outside", "negative pixel")
check(tostring(img):find("33x33", 1, true), "image tostring")

-- threads give the same image; default camera and preset names work
local img1 = cdvr.render(box, {tf = white, camera = orbit, threads = 1})
local img3 = cdvr.render(box, {tf = white, camera = orbit, threads = 3})
check(cdvr.compare(img1, img3).psnr == math.huge, "thread count changes the image")
local dflt = cdvr.render(box, {tf = "grayscale"})
check(select(1, dflt:size()) == 512, "default camera is a 512x512 orbit")

-- compare
local c = cdvr.compare(box, box)
check(c.psnr == math.huge and c.mse == 0 and c.maxerr == 0, "identical volumes")
local other = cdvr.volume{dims = {17, 17, 17}}
c = cdvr.compare(box, other)
check(near(c.mse, 10000) and c.maxerr == 100 and near(c.psnr, 10 * math.log(255 ^ 2 / 10000, 10)), "known mse")
local img_bg = cdvr.render(box, {tf = white, camera = orbit, background = {1, 1, 1}})
check(cdvr.compare(img1, img_bg).psnr < 40, "background is composited in compare")
raises(function() cdvr.compare(box, img1) end, nil, "volume against image")
raises(function() cdvr.compare(box, cdvr.volume{dims = {2, 2, 2}}) end, "differ", "size mismatch")

-- float volumes: the TF is in their units, classified over their range
local f = cdvr.volume{dims = {17, 17, 17}, type = "f32"}
for z = 0, 16 do for y = 0, 16 do for x = 0, 16 do f:set(x, y, z, x < 8 and -3.5 or 7.25) end end end
check(select(1, f:window()) == -3.5 and select(2, f:window()) == 7.25, "float window = range")
-- seen from +y, screen right is -x: x < 8 (-3.5, clear) on the right, x >= 8 (7.25) left
local dense = cdvr.tf{ {6, 0, 0, 0, 0}, {7.25, 1, 1, 1, 0.5} }
local fi = cdvr.render(f, {tf = dense, camera = orbit})
check(select(4, fi:pixel(10, 16)) > 0.5 and select(4, fi:pixel(22, 16)) == 0,
      "float volume quantized over its range: " .. select(4, fi:pixel(10, 16)) .. " " .. select(4, fi:pixel(22, 16)))

-- misuse raises
raises(function() cdvr.render(box) end, nil, "render without options")
raises(function() cdvr.render(box, {camera = orbit}) end, "tf", "render without tf")
raises(function() cdvr.render(box, {tf = white, camera = orbit, device = "gpu"}) end, "device", "bad device")
raises(function() cdvr.render(box, {tf = white, camera = orbit, t = 2}) end, "t = 2", "timestep out of range")
raises(function() cdvr.render(box, {tf = white, camera = orbit, step = -1}) end, "step", "negative step")
raises(function() cdvr.render(box, {tf = white, camera = orbit, background = {2, 0, 0}}) end, "background", "bad background")
raises(function() cdvr.render(box, {tf = white, camera = "cam"}) end, nil, "camera of the wrong type")
raises(function() cdvr.render("box", {tf = white}) end, nil, "render a string")

-- real data: PNG of the engine CT
local data = os.getenv("CDVR_SHARED_DATA")
if data then
  local engine = assert(cdvr.load(data .. "/ct/engine_256x256x128_u8.nrrd"))
  local ecam = cdvr.orbit_camera(engine, {azimuth = -60, elevation = 25, width = 128, height = 128})
  local eimg = cdvr.render(engine, {tf = "ct_bone", camera = ecam, step = 1})
  local png = tmpdir .. "/test_render_engine_lua.png"
  check(eimg:save(png) == true, "engine PNG saved")
  local fh = io.open(png, "rb")
  check(fh and fh:read(8) == "\137PNG\r\n\26\n", "PNG signature")
  if fh then fh:close() end
  local nv, nmsg = eimg:save("/nonexistent-dir/x.png")
  check(nv == nil and nmsg:find("nonexistent-dir", 1, true), "img:save to a bad path returns nil, msg")
else
  print("CDVR_SHARED_DATA not set: engine render skipped")
end

checks.finish()
