-- Captures never lose a frame silently (issue 21 item 6). From a store with one damaged chunk
-- (a patched byte with its CRC left wrong; patched LZO bytes with the chunk CRC and the
-- metadata CRC recomputed, so only the decoder can tell):
--  - a capture stops at the frame that cannot be made, with an error naming the frame, the
--    timestep, the chunk and the store; the frames before it are written, none after;
--  - on_error="skip" writes a marked frame (opaque red border and cross over the background)
--    in its place, plays on, and p:run raises at the end naming the count and the first;
--    through the CLI the script exits non-zero with every frame written;
--  - p:run{strict=false} returns the report (report.failed, rows[i].error); interactive
--    playback is not strict by default (rows keep their error), strict=true raises;
--  - option values: on_error other than stop/skip, or without out=, and bounded rates.
local tmpdir = os.tmpname()
os.remove(tmpdir)
assert(os.execute(("mkdir -p %q"):format(tmpdir)))
local function cleanup() os.execute(("rm -rf %q"):format(tmpdir)) end

local function crc32c(s) -- CRC-32C (Castagnoli, reflected 0x82F63B78), as core/base/crc32c.c
  local crc = 0xffffffff
  for i = 1, #s do
    crc = crc ~ s:byte(i)
    for _ = 1, 8 do crc = (crc >> 1) ~ (0x82F63B78 & -(crc & 1)) end
  end
  return crc ~ 0xffffffff
end

local function read(path) local f = assert(io.open(path, "rb")); local d = f:read("a"); f:close(); return d end
local function write(path, d) local f = assert(io.open(path, "wb")); f:write(d); f:close() end
local function exists(path) local f = io.open(path, "rb"); if f then f:close() end; return f ~= nil end

-- Damages the stored bytes of the chunk of store `path` whose index record is number k (from
-- 1: variant 1's chunks first) into `out`: 16 bytes from its 9th set to 0xff; with fix_crc the
-- chunk's CRC (record +76) and the metadata CRC (at M, over [0, M)) are recomputed.
local function damage(path, out, k, fix_crc)
  local data = read(path)
  local nvariants = string.unpack("<I4", data, 197)
  local meta = string.unpack("<I8", data, 17)
  local rec = 256 + 160 * nvariants + 128 * (k - 1)
  local off, size = string.unpack("<I8I8", data, rec + 81)
  local bytes = data:sub(off + 1, off + size)
  local bad = bytes:sub(1, 8) .. string.rep("\255", 16) .. bytes:sub(25)
  data = data:sub(1, off) .. bad .. data:sub(off + size + 1)
  if fix_crc then
    data = data:sub(1, rec + 76) .. string.pack("<I4", crc32c(bad)) .. data:sub(rec + 81)
    data = data:sub(1, meta) .. string.pack("<I4", crc32c(data:sub(1, meta))) .. data:sub(meta + 5)
  end
  write(out, data)
end

local vol = cdvr.generate("sphere", {dims = {16, 16, 16}, timesteps = 5})
local path = tmpdir .. "/s.cdv"
local st = assert(cdvr.encode(vol, {variants = {{codec = "raw", stage2 = "lzo"}}, path = path, progress = false}))
local _, info = st:chunk(3, "raw")
assert(info.t0 == 3 and info.stage2, "chunk 3 = timestep 3, stored with LZO")
local tf = cdvr.tf("hot")
local cam = cdvr.orbit_camera(vol, {width = 24, height = 20})

local cases = {{tmpdir .. "/crc.cdv", false, "CRC"}, {tmpdir .. "/lzo.cdv", true, "decode"}}
for _, case in ipairs(cases) do
  local bad, fix = case[1], case[2]
  damage(path, bad, 3, fix)
  local bst = assert(cdvr.open(bad))
  -- 1. the capture stops at the damaged frame, naming the timestep, the chunk and the store
  local dir = tmpdir .. "/stop" .. case[3]
  local p = cdvr.player{store = bst, tf = tf, camera = cam, device = "cpu", out = dir .. "/%04d.png"}
  local ok, msg = pcall(p.run, p, {frames = 5})
  assert(not ok, "a capture with a damaged chunk raised")
  msg = tostring(msg)
  for _, want in ipairs{"frame 3", "timestep 3", "chunk 3", bad, "on_error"} do
    assert(msg:find(want, 1, true), ("%s: '%s' lacks '%s'"):format(case[3], msg, want))
  end
  assert(exists(dir .. "/0001.png") and exists(dir .. "/0002.png"), "frames before the damage written")
  for i = 3, 5 do assert(not exists(("%s/%04d.png"):format(dir, i)), "nothing from frame 3 on") end
  p:close()

  -- 2. on_error="skip": a marked frame in its place, the rest plays, p:run raises at the end
  dir = tmpdir .. "/skip" .. case[3]
  local seen = {}
  p = cdvr.player{store = bst, tf = tf, camera = cam, device = "cpu", out = dir .. "/%04d.png", on_error = "skip",
                  background = {0, 0, 1}, frame = function(row, img) seen[row.frame] = {row = row, img = img} end}
  ok, msg = pcall(p.run, p, {frames = 5})
  assert(not ok and tostring(msg):find("1 of 5 frames", 1, true) and tostring(msg):find("timestep 3", 1, true)
         and tostring(msg):find("chunk 3", 1, true), tostring(msg))
  for i = 1, 5 do assert(exists(("%s/%04d.png"):format(dir, i)), "frame " .. i .. " written") end
  local m = seen[3]
  assert(m and m.row.error and m.row.error:find("chunk 3", 1, true), "frame= got the failed row")
  local function red(x, y) -- premultiplied opaque red
    local r, g, b, a = m.img:pixel(x, y)
    return r > 0.99 and g < 0.01 and b < 0.01 and a > 0.99
  end
  assert(red(0, 0) and red(23, 19) and red(0, 10), "the border is red")
  assert(red(12, 10) and red(6, 5) and red(18, 5), "the cross is red")
  local _, _, _, a = m.img:pixel(12, 3)
  assert(a == 0, "elsewhere nothing over the background")
  assert(read(dir .. "/0003.png") ~= read(dir .. "/0002.png"), "the marked frame is not a copy of another")
  p:close()

  -- 3. strict=false: the report says what failed
  p = cdvr.player{store = bst, tf = tf, camera = cam, device = "cpu", out = tmpdir .. "/ns/%04d.png", on_error = "skip"}
  local rep = p:run{frames = 5, strict = false}
  assert(rep.failed == 1 and rep.frames[3].error and not rep.frames[2].error and #rep.frames == 5)
  p:close()
  p = cdvr.player{store = bst, tf = tf, camera = cam, device = "cpu", out = tmpdir .. "/ns2/%04d.png"}
  rep = p:run{frames = 5, strict = false}
  assert(rep.failed == 1 and #rep.frames == 3 and rep.error and rep.error:find("timestep 3", 1, true),
         "a stopped capture that is not strict reports where it stopped")
  p:close()

  -- 4. interactive playback: not strict by default (as before), strict=true raises
  p = cdvr.player{store = bst, tf = tf, camera = cam, device = "cpu"}
  rep = p:run{frames = 5}
  assert(#rep.frames == 5 and rep.failed == 1 and rep.frames[3].error:find("chunk 3", 1, true))
  ok, msg = pcall(p.run, p, {frames = 5, strict = true})
  assert(not ok and tostring(msg):find("timestep 3", 1, true), tostring(msg))
  p:close()
  bst:close()
end

-- 5. the CLI: a skipping capture writes every frame and exits non-zero
local exe = arg and arg[-1]
if exe then
  local dir = tmpdir .. "/cli"
  local code = ("local st = assert(cdvr.open(%q)); local p = cdvr.player{store = st, tf = cdvr.tf('hot'), width = 16, " ..
                "height = 16, device = 'cpu', out = %q, on_error = 'skip'}; p:run{frames = 5}")
               :format(cases[1][1], dir .. "/%04d.png")
  local okx, how, rc = os.execute(("%q -e %q 2>%q"):format(exe, code, tmpdir .. "/cli.err"))
  assert(not okx and how == "exit" and rc ~= 0, "the CLI exits non-zero")
  assert(read(tmpdir .. "/cli.err"):find("1 of 5 frames", 1, true))
  for i = 1, 5 do assert(exists(("%s/%04d.png"):format(dir, i)), "CLI frame " .. i .. " written") end
else
  io.stderr:write("no executable path in arg[-1]: the CLI case is skipped\n")
end

-- 6. option values
local function fails(want, f, ...)
  local ok, msg = pcall(f, ...)
  assert(not ok and tostring(msg):find(want, 1, true), ("'%s' lacks '%s'"):format(tostring(msg), want))
end
fails("option 'on_error' = \"ignore\"", cdvr.player, {store = st, tf = tf, out = tmpdir .. "/x/%d.png", on_error = "ignore"})
fails("option 'on_error' applies to captures", cdvr.player, {store = st, tf = tf, on_error = "skip"})
fails("option 'read_mbps' = 1e-300", cdvr.player, {store = st, tf = tf, read_mbps = 1e-300})
fails("option 'target_fps' = 1e-300", cdvr.player, {store = st, tf = tf, target_fps = 1e-300})
fails("step 1e-06 is below 1/64", cdvr.player, {store = st, tf = tf, step = 1e-6})
local p = cdvr.player{store = st, tf = tf, camera = cam, device = "cpu"}
fails("option 'strict'", p.run, p, {strict = 3})
p:close()

st:close()
cleanup()
print("test_capture_errors: ok")
