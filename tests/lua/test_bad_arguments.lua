-- Bad arguments get clear errors when they are given (issue 11 items 3, 7, 8):
--   out= takes exactly one integer conversion and is never used as a printf format;
--   player options are checked when the player is made;
--   messages name the option or argument (no "bad argument #-1", no teem error chain, no
--   internal error from inside share/lua/cdvr/policy.lua or schedule.lua).
local tmpdir = os.tmpname()
os.remove(tmpdir)
assert(os.execute(("mkdir -p %q"):format(tmpdir)))

local vol = cdvr.generate("sphere", {dims = {12, 12, 12}, timesteps = 6})
local st = assert(cdvr.encode(vol, {variants = {{S = 4, T = 3}, {codec = "raw"}}, stage2 = "none",
                                    path = tmpdir .. "/s.cdv", progress = false}))
local tf = cdvr.tf("hot")

local function player(extra)
  local opts = {store = st, tf = tf, width = 8, height = 8, device = "cpu"}
  for k, v in pairs(extra) do opts[k] = v end
  return cdvr.player(opts)
end

local function fails(want, f, ...)
  local ok, msg = pcall(f, ...)
  assert(not ok, "expected an error containing '" .. want .. "'")
  msg = tostring(msg)
  assert(msg:find(want, 1, true), ("error '%s' lacks '%s'"):format(msg, want))
  assert(not msg:find("#-1", 1, true), "bad argument #-1: " .. msg)
  return msg
end

-- 3. out=: exactly one integer conversion; anything else is refused before playing
for _, bad in ipairs{"%s", "%n", "%f", "%x", "%5$d", "%*d", "%lld", "%hd", "%", "%d%d", "%d%s", "plain.png", "%%d",
                     "%123d", "%.1234d"} do
  local msg = fails("option 'out'", player, {out = tmpdir .. "/o/f" .. bad .. ".png"})
  assert(msg:find("integer conversion", 1, true), msg)
end
local function names(pattern, frames)
  local dir = tmpdir .. "/" .. pattern:gsub("[^%w]", "_")
  local p = player{out = dir .. "/" .. pattern}
  p:run{frames = frames or 2}
  p:close()
  local got = {}
  local ls = assert(io.popen(("ls %q"):format(dir)))
  for name in ls:lines() do got[#got + 1] = name end
  ls:close()
  return table.concat(got, "|")
end
assert(names("f%d.png") == "f1.png|f2.png")
assert(names("f%04d.png") == "f0001.png|f0002.png")
assert(names("f%3i.png") == "f  1.png|f  2.png")
assert(names("f%-3d.png") == "f1  .png|f2  .png")
assert(names("f%+.2d.png") == "f+01.png|f+02.png")
assert(names("%%s_%02d_%%n.png") == "%s_01_%n.png|%s_02_%n.png", "%% stays a literal percent")

-- 7. player options checked when the player is made
local nan, inf = 0 / 0, math.huge
local bad_options = {
  {"step", nan}, {"step", -1}, {"step", inf}, {"step", 1e-300}, {"unit", nan}, {"unit", -2}, {"unit", inf},
  {"term", nan}, {"term", -1}, {"term", inf}, {"width", 0}, {"width", 65537}, {"width", 1.5}, {"height", -5},
  {"height", 100000}, {"ring", 0}, {"ring", 65}, {"ring", 2e6}, {"threads", -1}, {"threads", 257},
  {"read_mbps", -1}, {"read_mbps", nan}, {"target_fps", 0}, {"target_fps", nan}, {"target_fps", -30},
  {"callback_limit", 0}, {"callback_limit", 2 ^ 40}, {"background", {nan, 0, 0}}, {"background", {1, 1}},
  {"background", {2, 0, 0, 1}}, {"min_psnr", nan},
}
for _, case in ipairs(bad_options) do
  local key, value = case[1], case[2]
  local extra = {[key] = value}
  if key == "min_psnr" then extra.out = tmpdir .. "/m/%d.png" end
  fails("option '" .. key .. "'", player, extra)
end
for _, good in ipairs{{step = 0.25, unit = 2, term = 0.9}, {term = 1.5}, {width = 65536, height = 1}, {ring = 64},
                      {ring = 1, threads = 256, read_mbps = 0, target_fps = 1e-3}, {background = {0, 0.5, 1}}} do
  player(good):close()
end

-- 8. messages name the option, never "bad argument #-1"
fails("option 'store': cdvr.Store expected, got nil", cdvr.player, {tf = tf})
fails("option 'store': cdvr.Store expected, got cdvr.TF", cdvr.player, {store = tf, tf = tf})
fails("option 'tf': cdvr.TF expected, got number", cdvr.player, {store = st, tf = 3})
fails("option 'tf': cdvr.TF expected, got number", cdvr.render, vol, {tf = 3})
fails("option 'camera': cdvr.Camera expected, got cdvr.Volume", cdvr.render, vol, {tf = tf, camera = vol})
fails("dims[2]: number expected", cdvr.orbit_camera, {1, "x", 3})
if cdvr.splat_order then
  fails("option 'volume': cdvr.Volume expected, got number", cdvr.splat_order, {4, 4, 4}, {1, 0, 0}, "dda",
        {threshold = 1, volume = 5})
end

-- teem's error chain is cut to its reason: one line, no "[nrrd]" function names
local bad = tmpdir .. "/bad.nrrd"
local f = assert(io.open(bad, "wb"))
f:write("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4\nencoding: raw\n\n")
f:close()
local ok, v, msg = pcall(cdvr.load, bad)
msg = ok and msg or v
assert(type(msg) == "string" and msg:find("bad.nrrd", 1, true), tostring(msg))
assert(not msg:find("[nrrd]", 1, true) and not msg:find("\n"), "teem chain not cut: " .. msg)

-- a series whose files differ in spacing is an error naming the file, unless spacing= is given
local function nrrd(name, spacing)
  local g = assert(io.open(tmpdir .. "/" .. name, "wb"))
  g:write(("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspacings: %g 1 1\nencoding: raw\n\n"):format(spacing))
  g:write(("\0"):rep(8))
  g:close()
  return tmpdir .. "/" .. name
end
local files = {nrrd("sp1.nrrd", 1), nrrd("sp2.nrrd", 2)}
local ok2, s1, m1 = pcall(cdvr.load_series, files)
m1 = ok2 and m1 or s1
assert(type(m1) == "string" and m1:find("sp2.nrrd", 1, true) and m1:find("spacing="), tostring(m1))
local series = cdvr.load_series(files, {spacing = {0.5, 1, 1}})
assert(select(1, series:spacing()) == 0.5 and #series == 2)

-- policy.lua and schedule.lua: bad user input is named, never an internal error from inside them
local policy, schedule = require "cdvr.policy", require "cdvr.schedule"
local function stats()
  return {target_fps = 30, t = 4, group = 2, current = "A",
          frames = {{t = 1, variant = "A", read_ms = 1, decode_ms = 1, render_ms = 2, frame_ms = 4, bytes = 100,
                     payload_bytes = 100}},
          variants = {{name = "A", codec = "pvtc", bytes_per_timestep = 100, psnr = 30, group = 3},
                      {name = "B", codec = "raw", bytes_per_timestep = 1000, group = 1}}}
end
local function named(want, f, ...)
  local msg = fails(want, f, ...)
  assert(not msg:find("attempt to", 1, true) and not msg:find("to 'format'", 1, true), "internal error: " .. msg)
end
for _, ctor in ipairs{"open_loop", "closed_loop"} do
  local p = policy[ctor]{}
  local s = stats(); s.frames[2] = 42
  named("stats.frames[2] must be a table", p, s)
  s = stats(); s.frames = "x"
  named("stats.frames must be a table", p, s)
  s = stats(); s.capture = true; s.min_psnr = "high"
  named("stats.min_psnr must be a number", p, s)
  s = stats(); s.current = 7
  named("stats.current must be a variant name", p, s)
  named("target_fps must be a positive number", policy[ctor], {target_fps = "30"})
  named("variant must be a variant name", policy[ctor], {variant = 2})
end
named("window must be a positive integer", policy.closed_loop, {window = "4"})
named("up_after must be a positive integer", policy.closed_loop, {up_after = "2"})
named("memory must be an integer", policy.closed_loop, {memory = "x"})
named("frames[1] must be a table", policy.measure, {5})
named("bad argument #1 to 'predict'", policy.predict, 5, policy.measure(stats().frames))
named("bad argument #2 to 'predict'", policy.predict, stats().variants[1], 5)
named("bad argument #1 to 'quantile'", schedule.quantile, 5, 0.5)
named("values[2] must be a number", schedule.quantile, {1, "x"}, 0.5)
named("bad argument #2 to 'quantile'", schedule.quantile, {1, 2}, "half")
named("bad argument #2 to 'from_changes'", schedule.from_changes, {1, 2}, 5)
named("bad argument #2 to 'change_driven'", schedule.change_driven, vol, 5)

st:close()
os.execute(("rm -rf %q"):format(tmpdir))
print("test_bad_arguments: ok")
