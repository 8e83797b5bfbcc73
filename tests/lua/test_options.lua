-- tests/lua/test_options.lua - misspelled options are errors (issue 10, item 6): every
-- function taking an options table (C bindings except the store/device ones, and the Lua
-- modules of share/lua/cdvr) rejects an unknown key, naming the function and suggesting the
-- closest known option; the right spelling works.
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check = checks.check
local function rejects(expected, what, f, ...)
  local ok, msg = pcall(f, ...)
  check(not ok and tostring(msg):find(expected, 1, true),
        what .. ": expected an error with \"" .. expected .. "\", got " .. tostring(msg))
end
local tmpdir = os.getenv("CDVR_BINARY_DIR") or "."

local v = cdvr.generate("sphere", {dims = {12, 10, 8}, timesteps = 2})
local tf = cdvr.tf("hot")
local cam = cdvr.orbit_camera(v, {width = 16, height = 16})

-- the issue's example, word for word
rejects("cdvr.render: unknown option 'devcie' (did you mean 'device'?)", "render devcie",
        cdvr.render, v, {tf = tf, devcie = "cl"})
rejects("cdvr.render: unknown option 'stpe' (did you mean 'step'?)", "render stpe",
        cdvr.render, v, {tf = tf, camera = cam, stpe = 0.5})
rejects("cdvr.render: unknown option 'colour'", "render, no close name", cdvr.render, v, {tf = tf, colour = 1})
rejects("option keys must be names", "render, a number key", cdvr.render, v, {tf = tf, [1] = 2})

-- volumes
rejects("cdvr.load: unknown option 'endain' (did you mean 'endian'?)", "load",
        cdvr.load, "x.raw", {dims = {2, 2, 2}, type = "u8", endain = "big"})
rejects("cdvr.load_series: unknown option 'frist' (did you mean 'first'?)", "load_series",
        cdvr.load_series, "x%d.raw", {frist = 2})
rejects("cdvr.volume: unknown option 'dim' (did you mean 'dims'?)", "volume", cdvr.volume, {dim = {2, 2, 2}})
rejects("cdvr.generate: unknown option 'radus' (did you mean 'radius'?)", "generate",
        cdvr.generate, "sphere", {radus = 0.5})
rejects("v:quantize: unknown option 'low' (did you mean 'lo'?)", "quantize", v.quantize, v, {low = 0})
rejects("v:save_raw: unknown option 'endien' (did you mean 'endian'?)", "save_raw",
        v.save_raw, v, tmpdir .. "/test_options.raw", {endien = "big"})
check(not io.open(tmpdir .. "/test_options.raw"), "nothing written after a misspelled option")

-- transfer functions, cameras, images
rejects("cdvr.tf: unknown option 'unti' (did you mean 'unit'?)", "tf table",
        cdvr.tf, {{0, 0, 0, 0, 0}, {255, 1, 1, 1, 1}, unti = 2})
rejects("cdvr.tf: unknown option 'rnage' (did you mean 'range'?)", "tf options", cdvr.tf, "hot", {rnage = {0, 1}})
check(cdvr.tf({{0, 0, 0, 0, 0}, {255, 1, 1, 1, 1}, unit = 2}):unit() == 2, "tf with a correct option")
rejects("cdvr.camera: unknown option 'centre' (did you mean 'center'?)", "camera",
        cdvr.camera, {eye = {0, -5, 0}, centre = {0, 0, 0}})
rejects("cam:set: unknown option 'fow' (did you mean 'fov'?)", "cam:set", cam.set, cam, {fow = 40})
rejects("cdvr.orbit_camera: unknown option 'azimut' (did you mean 'azimuth'?)", "orbit_camera",
        cdvr.orbit_camera, v, {azimut = 30})
local img = cdvr.render(v, {tf = tf, camera = cam})
rejects("img:save: unknown option 'alhpa' (did you mean 'alpha'?)", "img:save",
        img.save, img, tmpdir .. "/test_options.png", {alhpa = true})

-- player (the store comes from cdvr.encode, checked by its own binding)
local st = assert(cdvr.encode(v, {variants = {{codec = "raw"}}, path = tmpdir .. "/test_options.cdv", progress = false}))
rejects("cdvr.player: unknown option 'taget_fps' (did you mean 'target_fps'?)", "player",
        cdvr.player, {store = st, tf = tf, taget_fps = 30})
local p = cdvr.player{store = st, tf = tf, camera = cam, policy = "closed_loop", target_fps = 30}
rejects("p:run: unknown option 'frame' (did you mean 'frames'?)", "p:run", p.run, p, {frame = 2})
check(#p:run{frames = 2}.frames == 2, "a named policy gets only its own options from the player")
p:close()
st:close()
os.remove(tmpdir .. "/test_options.cdv")

-- Lua modules
rejects("cdvr.path.orbit: unknown option 'perod' (did you mean 'period'?)", "path.orbit",
        cdvr.path.orbit, {center = {0, 0, 0}, distance = 5, perod = 10})
rejects("cdvr.path.keyframes: unknown option 'lop' (did you mean 'loop'?)", "path.keyframes",
        cdvr.path.keyframes, {{time = 0, eye = {1, 0, 0}, center = {0, 0, 0}}, lop = true})
rejects("cdvr.path.keyframes: key 1: unknown option 'tiem' (did you mean 'time'?)", "keyframes key",
        cdvr.path.keyframes, {{tiem = 0, eye = {1, 0, 0}, center = {0, 0, 0}}})
local orbit = cdvr.path.orbit{center = {0, 0, 0}, distance = 5, period = 10}
check(cdvr.path.is_path(cdvr.path.from(orbit:totable())), "path.from(totable) still works")
rejects("cdvr.policy.closed_loop: unknown option 'hysteresys' (did you mean 'hysteresis'?)", "closed_loop",
        cdvr.policy.closed_loop, {target_fps = 30, hysteresys = 0.2})
rejects("cdvr.policy.open_loop: unknown option 'margn' (did you mean 'margin'?)", "open_loop",
        cdvr.policy.open_loop, {target_fps = 30, margn = 0.8})
rejects("cdvr.policy.fixed: unknown option 'varient' (did you mean 'variant'?)", "policy.get fixed",
        cdvr.policy.get, "fixed", {varient = "raw"})
rejects("cdvr.schedule.from_changes: unknown option 'quantil' (did you mean 'quantile'?)", "from_changes",
        cdvr.schedule.from_changes, {1, 2, 3}, {quantil = 0.5})
rejects("cdvr.schedule.change_driven: unknown option 'fats' (did you mean 'fast'?)", "change_driven",
        cdvr.schedule.change_driven, v, {fats = {S = 1, T = 2}})

checks.finish()
