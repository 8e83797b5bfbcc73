-- tests/lua/window_checks.lua - cdvr.window under a display (tests/test_window.sh runs it with
-- xvfb-run): the framebuffer equals the offscreen render of the same scene, a change of TF,
-- camera, method or timestep shows in the next frame, store scenes step timesteps and variants,
-- the object holds its scene, misuse raises. Not collected by ctest on its own (needs a display).
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check, raises = checks.check, checks.raises
local function psnr(a, b) return cdvr.compare(a, b).psnr end

local vol = cdvr.generate("ml", {dims = {40, 36, 32}, timesteps = 1})
local hot = cdvr.tf("hot")
local w = cdvr.window{volume = vol, tf = hot, overlay = false, width = 160, height = 120}
check(tostring(w):find("cdvr.Window 160x120", 1, true), "tostring " .. tostring(w))
check(w:frame() == true, "frame")

-- the window shows exactly what cdvr.render makes of the same scene (8-bit framebuffer)
local shot = w:read()
check(select(1, shot:size()) == 160 and select(2, shot:size()) == 120, "read size")
local cam = w:camera()
check(cam.width == 160 and cam.height == 120, "camera sized to the framebuffer")
local ref = cdvr.render(vol, {tf = hot, camera = cam})
check(psnr(shot, ref) >= 50, "window vs offscreen ray casting: " .. psnr(shot, ref) .. " dB")

-- a TF change shows in the next frame
w:set{tf = "grayscale"}
w:frame()
local gray = w:read()
check(psnr(shot, gray) < 30, "TF change changes the frame: " .. psnr(shot, gray))
check(psnr(gray, cdvr.render(vol, {tf = cdvr.tf("grayscale"), camera = cam})) >= 50, "new TF rendered")

-- the slicer in the window, against the slicer offscreen
w:set{method = "slice", tf = hot}
w:frame()
local sliced = cdvr.render(vol, {tf = hot, camera = w:camera(), method = "slice"})
check(psnr(w:read(), sliced) >= 50, "window vs offscreen slicing: " .. psnr(w:read(), sliced))
check(w:state().method == "slice", "state method")

-- a camera set from the script is copied (the window's dragging does not move it)
local c2 = cdvr.orbit_camera(vol, {azimuth = 90, width = 10, height = 10})
w:set{camera = c2, method = "raycast"}
w:frame()
check(c2.width == 10 and w:camera().width == 160, "script camera untouched, window sized")
check(psnr(w:read(), cdvr.render(vol, {tf = hot, camera = w:camera()})) >= 50, "new camera rendered")

-- the overlay draws a line on top; overlay=false hides it
w:set{overlay = true}
w:frame()
check(psnr(w:read(), cdvr.render(vol, {tf = hot, camera = w:camera()})) < 50, "overlay drawn")
w:set{overlay = false}

-- a store scene: timesteps, variants by name, decoded with the store's own decoder
local tmp = os.tmpname()
local series = cdvr.generate("sphere", {dims = {24, 22, 20}, timesteps = 4})
local st = cdvr.encode(series, {variants = {{codec = "raw"}, {S = 4, T = 2}}, stage2 = "none", path = tmp})
w:set{store = st, t = 3, variant = 2, camera = false}
w:frame()
local s = w:state()
check(s.t == 3 and s.variant == st:variants()[2] and s.reason:find("set by the user", 1, true),
      "store state: " .. tostring(s.t) .. " " .. tostring(s.variant) .. " " .. tostring(s.reason))
local frame3 = st:decode(3, 2)
check(psnr(w:read(), cdvr.render(frame3, {tf = hot, camera = w:camera()})) >= 50, "store frame t=3")
w:set{t = 1}
w:frame()
check(psnr(w:read(), cdvr.render(st:decode(1, 2), {tf = hot, camera = w:camera()})) >= 50,
      "timestep change shows")
-- playing advances one timestep per frame and loops
w:set{playing = true, t = 4}
w:frame()
check(w:state().t == 1, "playback loops to t = 1: " .. w:state().t)
w:frame()
check(w:state().t == 2, "playback advances")
-- a policy picks the variant at group boundaries, its reason is kept for the overlay
w:set{policy = function(stats)
  assert(stats.t and stats.variants and #stats.variants == 2 and stats.frames)
  return stats.variants[1].name, "test policy: first variant"
end}
for _ = 1, 4 do w:frame() end
check(w:state().reason == "test policy: first variant" and w:state().variant == st:variants()[1],
      "policy reason: " .. w:state().reason)
w:set{playing = false}

-- the mouse and the keys, through the X server (tests/xinput.py: XTEST); without a display
-- window manager the window sits at the screen's top-left corner
local src = os.getenv("CDVR_SOURCE_DIR") or "."
local function xinput(args)
  local ok, _, code = os.execute("python3 " .. src .. "/tests/xinput.py " .. args)
  return ok and 0 or code
end
local function settle(cond) -- the events reach the window asynchronously
  for _ = 1, 100 do
    w:frame()
    if cond() then return true end
    os.execute("sleep 0.02")
  end
  return false
end
local function dist(c)
  local s = 0
  for i = 1, 3 do s = s + (c.eye[i] - c.center[i]) ^ 2 end
  return math.sqrt(s)
end
w:set{volume = vol, camera = false, t = 1}
w:frame()
local before = w:camera()
local code = xinput("drag 60 60 120 60")
if code == 77 then
  print("XTEST input unavailable: mouse and key checks skipped")
else
  check(code == 0, "xinput drag")
  check(settle(function() return w:camera().eye[1] ~= before.eye[1] end), "drag orbits the camera")
  check(math.abs(dist(w:camera()) - dist(before)) < 1e-6 * dist(before), "orbit keeps the distance")
  local frame_before = w:read()
  w:frame()
  check(psnr(frame_before, cdvr.render(vol, {tf = hot, camera = w:camera()})) >= 50, "orbited frame shown")
  local d0 = dist(w:camera())
  check(xinput("scroll 2") == 0, "xinput scroll")
  check(settle(function() return math.abs(dist(w:camera()) - 0.81 * d0) < 1e-6 * d0 end),
        "two wheel steps zoom in by 0.9^2: " .. dist(w:camera()) / d0)
  w:set{volume = series, t = 1}
  check(xinput("key Right") == 0 and settle(function() return w:state().t == 2 end), "right arrow")
  check(xinput("key Right") == 0 and settle(function() return w:state().t == 3 end),
        "right arrow steps t: " .. w:state().t)
  check(xinput("key Left") == 0 and settle(function() return w:state().t == 2 end), "left arrow")
  check(xinput("key space") == 0 and settle(function() return w:state().playing end), "space plays")
  check(xinput("key space") == 0 and settle(function() return not w:state().playing end), "space pauses")
  -- m records the frames drawn to a movie and stops (the movie is committed), p saves a PNG
  if cdvr.has_movie then
    check(xinput("key m") == 0 and settle(function() return w:state().recording ~= nil end), "m starts recording")
    local movie = w:state().recording
    w:set{t = 3}
    w:frame()
    check(movie:match("^cdvr%-movie%-%d+%-%d+.*%.mp4$") and io.open(movie) == nil, "nothing under " .. movie .. " while recording")
    check(xinput("key m") == 0 and settle(function() return w:state().recording == nil end), "m stops recording")
    local f = io.open(movie, "rb")
    check(f and #f:read("a") > 0, "the recording is written: " .. movie)
    if f then f:close() end
    os.remove(movie)
  end
  check(xinput("key p") == 0 and settle(function() return w:state().screenshot ~= nil end), "p saves a screenshot")
  local shot = w:state().screenshot or "none"
  local png = io.open(shot, "rb")
  check(png and png:read(8) == "\137PNG\r\n\26\n", "the screenshot is a PNG: " .. shot)
  if png then png:close() end
  os.remove(shot)
  -- screenshots at a scale of the window's size: the p key (screenshot_scale=) and w:screenshot
  local function png_size(path)
    local f = io.open(path, "rb")
    if not f then return 0, 0 end
    local head = f:read(24); f:close()
    return string.unpack(">I4I4", head, 17)
  end
  local ww, wh = w:state().width, w:state().height
  w:set{screenshot_scale = 2}
  check(xinput("key p") == 0 and settle(function() local s = w:state().screenshot; return s and s ~= shot end),
        "p saves a scaled screenshot")
  local big = w:state().screenshot or "none"
  local bw, bh = png_size(big)
  check(bw == 2 * ww and bh == 2 * wh, ("screenshot_scale=2: %dx%d from a %dx%d window"):format(bw, bh, ww, wh))
  os.remove(big)
  local named = os.tmpname() .. ".png"
  check(w:screenshot(named, {scale = 3}) == named, "w:screenshot returns its path")
  bw, bh = png_size(named)
  check(bw == 3 * ww and bh == 3 * wh, ("w:screenshot scale=3: %dx%d"):format(bw, bh))
  os.remove(named)
  local jpg = os.tmpname() .. ".jpg"
  w:screenshot(jpg)
  local jf = io.open(jpg, "rb")
  check(jf and jf:read(2) == "\255\216", "w:screenshot to .jpg writes a JPEG")
  if jf then jf:close() end
  os.remove(jpg)
  raises(function() w:screenshot{scale = 9} end, "scale = 9: must be 1..8", "scale beyond 8")
  raises(function() w:screenshot{zoom = 2} end, "unknown option 'zoom'", "w:screenshot option check")
  raises(function() w:set{screenshot_scale = 0} end, "'screenshot_scale' = 0: must be 1..8", "screenshot_scale 0")
  w:set{screenshot_scale = 1}
  w:set{store = st, t = 1}
end

-- the method table: the options follow the method, the look reaches the renderer, and the
-- method's own keys ('l' cycles slice's lod) reach it
w:set{volume = vol, method = "slice", lod = "screen", t = 1}
check(w:state().method == "slice" and w:state().device == "gl", "slice in the window: " .. w:state().device)
raises(function() w:set{step = 0.5} end, "unknown option 'step'", "slice takes no step")
if code ~= 77 then
  check(xinput("key l") == 0 and settle(function() return w:state().options.lod == false end),
        "l cycles lod: screen -> false (" .. tostring(w:state().options.lod) .. ")")
end
if code ~= 77 then -- b and a toggle the colour bar and the orientation letters
  check(xinput("key b") == 0 and settle(function()
    local a = w:state().options.annotate
    return a and a.colorbar == true and a.axes == false end), "b turns the colour bar on")
  check(xinput("key a") == 0 and settle(function() return w:state().options.annotate.axes == true end),
        "a turns the letters on")
  check(xinput("key b") == 0 and settle(function() return w:state().options.annotate.colorbar == false end),
        "b turns the colour bar off")
end
w:set{method = "raycast"} -- lod is slice's: dropped
check(w:state().options.lod == nil and w:state().method == "raycast", "a new method drops the old one's options")
raises(function() w:set{lod = true} end, "unknown option 'lod'", "raycast takes no lod")
w:set{step = 0.4, shade = true}
w:frame()
local shaded = w:read()
w:set{shade = false}
w:frame()
check(psnr(shaded, w:read()) < 40, "shade= reaches the renderer: " .. psnr(shaded, w:read()) .. " dB")
w:set{blend = "max"}
w:frame()
check(psnr(shaded, w:read()) < 40 and w:state().options.blend == "max", "blend= in the window")
w:set{blend = "composite", step = 0, store = st, t = 1}

-- misuse
raises(function() w:set{tf = 3} end, nil, "tf of the wrong type")
raises(function() w:set{methd = "slice"} end, "did you mean 'method'", "misspelled key")
raises(function() w:set{method = "mip"} end, "unknown method 'mip' (methods: raycast, slice, splat)", "unknown method")
raises(function() w:set{t = 9} end, "outside 1..4", "timestep out of range")
raises(function() w:set{variant = "nope"} end, 'no variant "nope"', "unknown variant")
raises(function() w:set{width = 3} end, "fixed when the window opens", "width after opening")
raises(function() cdvr.window{volume = vol, devize = "cpu"} end, "did you mean 'device'", "misspelled open key")

-- the window holds its scene: the store stays usable while shown
st = nil
collectgarbage()
w:set{t = 2}
check(w:frame(), "scene kept alive by the window")

-- a store scene through the brick cache (cache=true): exactly cdvr.render(st, {cache=true}); a
-- moved camera (here set from the script) renders at moving_lod, and once the camera has been
-- still for settle_ms (0 here, so no wall-clock wait: cdvr/refine.h's timing is test_refine's)
-- the next frame renders at the requested lod_error
do
  local ltmp = os.tmpname()
  local lst = cdvr.encode(cdvr.generate("sphere", {dims = {40, 36, 30}, timesteps = 2}),
                          {path = ltmp, levels = 3, bricks = {2, 2, 2}, progress = false,
                           variants = {{codec = "raw"}}})
  w:set{store = lst, t = 2, tf = hot, camera = false, method = "raycast", device = "cpu", policy = false,
        cache = true, lod_error = 0, moving_lod = 1e6, settle_ms = 0}
  w:frame()
  local function ref(lod) -- the window's render options (annotate=, ... set above) and lod
    local o = {t = 2, tf = hot, camera = w:camera(), device = "cpu"}
    for k, v in pairs(w:state().options) do o[k] = v end
    o.lod_error = lod
    return cdvr.render(lst, o)
  end
  check(w:state().lod_error == 0, "a first cached frame at the requested lod_error: " ..
        tostring(w:state().lod_error))
  check(psnr(w:read(), ref(0)) >= 50, "cached window frame = cdvr.render through the cache")
  w:set{camera = cdvr.orbit_camera(lst, {azimuth = 70, elevation = 10})}
  w:frame()
  check(w:state().lod_error == 1e6, "moving: moving_lod (" .. tostring(w:state().lod_error) .. ")")
  local coarse, fine = ref(1e6), ref(0)
  check(psnr(w:read(), coarse) >= 50 and psnr(coarse, fine) < 50,
        "the moving frame is the coarse render: " .. psnr(w:read(), coarse) .. " dB")
  w:frame() -- settle_ms 0: the frame after the moving one refines, however slow the machine
  check(w:state().lod_error == 0 and psnr(w:read(), fine) >= 50,
        "still for settle_ms: refined (" .. tostring(w:state().lod_error) .. ")")
  raises(function() w:set{settle_ms = -1} end, "settle_ms", "settle_ms < 0")
  w:set{volume = vol, cache = false}
  lst:close()
  os.remove(ltmp)
end

-- an empty window draws a notice, closing is final
local empty = cdvr.window{width = 64, height = 48}
check(empty:frame() and select(1, empty:read():size()) == 64, "empty window")
empty:close()
check(tostring(empty) == "cdvr.Window (closed)", "closed tostring")
raises(function() empty:frame() end, "closed window", "use after close")
w:close()
w:close()
os.remove(tmp)

checks.finish()
os.exit(0)
