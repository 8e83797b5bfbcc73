-- Player: one row per frame with every stage timing, serial and pipelined, cpu and cl;
-- a corrupt chunk gives an error row and the rest plays; policies and camera callbacks;
-- capture writes byte-identical frames; misuse raises.
local tmpdir = os.tmpname()
os.remove(tmpdir)
assert(os.execute(("mkdir -p %q"):format(tmpdir)))
local function cleanup() os.execute(("rm -rf %q"):format(tmpdir)) end

local vol = cdvr.generate("sphere", {dims = {21, 19, 17}, timesteps = 8})
local path = tmpdir .. "/s.cdv"
local st = assert(cdvr.encode(vol, {variants = {{S = 4, T = 3}, {S = 1, T = 2, pack = "space"},
                                                {codec = "raw"}}, stage2 = "none", path = path}))
local tf = cdvr.tf("hot")
local cam = cdvr.orbit_camera(vol, {azimuth = 30, elevation = 20, width = 48, height = 40})
local stages = {"read_ms", "unzip_ms", "unzip_cpu_ms", "upload_ms", "decode_ms", "setup_ms",
                "render_ms", "frame_ms"}

local devices = {"cpu"}
if cdvr.cl_info() then devices[2] = "cl" end

local function check_rows(r, frames, first_t, ntimesteps)
  assert(#r.frames == frames, ("rows %d, expected %d"):format(#r.frames, frames))
  for i, row in ipairs(r.frames) do
    assert(row.frame == i)
    assert(row.t == (first_t - 1 + i - 1) % ntimesteps + 1, "timestep order")
    assert(type(row.variant) == "string")
    for _, k in ipairs(stages) do
      assert(type(row[k]) == "number" and row[k] >= 0, k .. " missing in row " .. i)
    end
    assert(row.render_ms > 0, "render time measured")
    assert(row.unzip_cpu_ms == 0, "no stage 2 here: no unzip CPU time")
  end
  for _, k in ipairs(stages) do
    assert(type(r.median[k]) == "number" and r.median[k] >= 0, k .. " missing in the medians")
  end
  assert(r.fps > 0)
end

-- 1. every device x serial/pipelined, each variant, wrapping around the series
for _, dev in ipairs(devices) do
  for _, pipe in ipairs{false, true} do
    for _, var in ipairs(st:variants()) do
      local p = cdvr.player{store = st, tf = tf, camera = cam, device = dev, pipeline = pipe, variant = var, loop = true}
      local r = p:run{frames = 11, first = 3}
      check_rows(r, 11, 3, 8)
      assert(r.device == dev and r.pipelined == pipe)
      for _, row in ipairs(r.frames) do
        assert(row.variant == var and not row.error)
      end
      assert(r.frames[1].reason, "the first frame records the decision")
      p:close()
    end
  end
end

-- 2. the player's frames equal cdvr.render of st:decode (same camera)
do
  local outpat = tmpdir .. "/a/%03d.png"
  local p = cdvr.player{store = st, tf = tf, camera = cam, device = "cpu", variant = "S4T3", out = outpat}
  p:run{frames = 2}
  p:close()
  local f = assert(io.open(tmpdir .. "/a/001.png", "rb"))
  local png = f:read("a")
  f:close()
  assert(png:sub(1, 8) == "\137PNG\r\n\26\n")
  local img = cdvr.render(st:decode(1, "S4T3"), {tf = tf, camera = cam, device = "cpu"})
  img:save(tmpdir .. "/ref.png")
  local g = assert(io.open(tmpdir .. "/ref.png", "rb"))
  assert(g:read("a") == png, "player frame differs from cdvr.render of the decoded timestep")
  g:close()
end

-- 3. captures are byte-identical, and never adapt below the user's quality
do
  local function capture(dir)
    local p = cdvr.player{store = st, tf = tf, camera = cdvr.path.orbit{center = {10, 9, 8}, distance = 80, period = 8},
                          width = 40, height = 40, out = dir .. "/%02d.png", policy = "closed_loop",
                          target_fps = 1e6, variant = "S1T2s"}
    local r = p:run{frames = 8}
    p:close()
    for _, row in ipairs(r.frames) do assert(row.variant == "S1T2s", "capture adapted: " .. row.variant) end
    return r
  end
  capture(tmpdir .. "/c1")
  capture(tmpdir .. "/c2")
  for i = 1, 8 do
    local a = assert(io.open(("%s/c1/%02d.png"):format(tmpdir, i), "rb")):read("a")
    local b = assert(io.open(("%s/c2/%02d.png"):format(tmpdir, i), "rb")):read("a")
    assert(a == b, "capture frame " .. i .. " differs between two runs")
  end
end

-- 4. policy and camera callbacks: calls at group boundaries, stats contract, reasons. Serial:
-- each decision sees exactly the frames shown before it. Pipelined: the reader decides ahead,
-- so a decision sees at most those frames, never a frame of its own group or later.
for _, pipe in ipairs{false, true} do
  local calls = {}
  local function policy(stats)
    calls[#calls + 1] = stats
    return (#calls % 2 == 1) and "S4T3" or "raw", "test policy call " .. #calls
  end
  local cams = 0
  local function camfn(frame, t)
    cams = cams + 1
    return {eye = {10 + 60 * math.cos(frame), 9 + 60 * math.sin(frame), 30}, center = {10, 9, 8}, up = {0, 0, 1}, fov = 30}
  end
  local p = cdvr.player{store = st, tf = tf, camera = camfn, width = 32, height = 32, policy = policy, target_fps = 30,
                        pace = false, pipeline = pipe}
  local r = p:run{frames = 8}
  p:close()
  assert(r.group_length == 3, "group length = lcm(3, 1, 1)")
  assert(#calls == 3, "decisions at t = 1, 4, 7: got " .. #calls)
  assert(calls[1].t == 1 and calls[2].t == 4 and calls[3].t == 7)
  assert(calls[1].target_fps == 30 and #calls[1].variants == 3)
  assert(calls[1].variants[1].name == "S4T3" and calls[1].variants[1].bytes_per_timestep > 0)
  assert(#calls[1].frames == 0 and calls[1].current == nil, "the first decision sees no frames")
  for k = 2, 3 do
    local seen = calls[k].frames
    if not pipe then
      assert(#seen == 3 * (k - 1), ("serial: decision %d saw %d frames, expected %d"):format(k, #seen, 3 * (k - 1)))
    end
    assert(#seen <= 3 * (k - 1), ("decision %d saw %d frames: more than were shown"):format(k, #seen))
    for i, row in ipairs(seen) do
      assert(row.t == i and row.frame == i, "frames in order, oldest first")
      assert(row.variant == (i <= 3 and "S4T3" or "raw"), "row variant")
      assert(row.read_ms >= 0 and row.render_ms > 0 and row.bytes > 0)
    end
    if #seen > 0 then assert(calls[k].current == seen[#seen].variant, "current is the last frame's variant") end
  end
  assert(cams == 8)
  assert(r.frames[1].variant == "S4T3" and r.frames[4].variant == "raw" and r.frames[7].variant == "S4T3")
  assert(r.frames[4].reason == "test policy call 2")
  assert(not r.frames[5].reason)
end

-- 5. a callback that raises or runs too long stops playback with its traceback
do
  local p = cdvr.player{store = st, tf = tf, camera = cam, policy = function() error("policy broke") end}
  local ok, msg = pcall(p.run, p, {frames = 3})
  assert(not ok and msg:find("policy broke") and msg:find("traceback"), msg)
  local q = cdvr.player{store = st, tf = tf, camera = cam, callback_limit = 100000,
                        policy = function() while true do end end}
  ok, msg = pcall(q.run, q, {frames = 3})
  assert(not ok and msg:find("instruction budget"), msg)
  local c = cdvr.player{store = st, tf = tf, camera = function() return 42 end}
  ok, msg = pcall(c.run, c, {frames = 1})
  assert(not ok and msg:find("camera"), msg)
  -- a name is matched over its whole length: "S4T3\0junk" is no variant (issue 21 item 5)
  local z = cdvr.player{store = st, tf = tf, camera = cam, policy = function() return "S4T3\0junk" end}
  ok, msg = pcall(z.run, z, {frames = 1})
  assert(not ok and msg:find('policy returned "S4T3\\0junk", not a variant of', 1, true), msg)
  ok, msg = pcall(cdvr.player, {store = st, tf = tf, variant = "S4T3\0"})
  assert(not ok and msg:find('has no variant "S4T3\\0"', 1, true), msg)
  ok, msg = pcall(cdvr.render, st, {tf = tf, camera = cam, variant = "raw\0x"})
  assert(not ok and msg:find('has no variant "raw\\0x"', 1, true), msg)
  ok, msg = pcall(st.decode, st, 1, "raw\0")
  assert(not ok and msg:find('no variant "raw\\0"', 1, true), msg)
end

-- 6. a corrupt chunk: its frames get error rows, the rest plays (serial and pipelined)
do
  local bytes, info = st:chunk(2, "raw")          -- raw chunk 2 = timestep 2, stored plainly
  assert(info.t0 == 2 and not info.stage2)
  local f = assert(io.open(path, "rb"))
  local data = f:read("a")
  f:close()
  local at = assert(data:find(bytes, 1, true), "chunk bytes located in the file")
  local pos = at + #bytes // 2
  local flipped = data:sub(1, pos - 1) .. string.char(data:byte(pos) ~ 0x5a) .. data:sub(pos + 1)
  local bad = tmpdir .. "/bad.cdv"
  f = assert(io.open(bad, "wb"))
  f:write(flipped)
  f:close()
  local bst = assert(cdvr.open(bad))
  for _, pipe in ipairs{false, true} do
    local p = cdvr.player{store = bst, tf = tf, camera = cam, variant = "raw", pipeline = pipe}
    local r = p:run{frames = 4}
    p:close()
    assert(#r.frames == 4)
    assert(r.frames[2].error and r.frames[2].error:find("chunk 2"), tostring(r.frames[2].error))
    assert(r.frames[2].error:find("bad.cdv", 1, true))
    for _, i in ipairs{1, 3, 4} do assert(not r.frames[i].error, "frame " .. i .. " played") end
  end
  bst:close()
end

-- 7. misuse raises
assert(not pcall(cdvr.player, {store = st}))
assert(not pcall(cdvr.player, {store = st, tf = tf, variant = "nope"}))
assert(not pcall(cdvr.player, {store = st, tf = tf, device = "quantum"}))
assert(not pcall(cdvr.player, {store = st, tf = tf, out = "frames.png"}))
local p = cdvr.player{store = st, tf = tf}
assert(not pcall(p.run, p, {frames = 0}))
assert(tostring(p):find("cdvr.Player"))
p:close()
assert(not pcall(p.run, p))

st:close()
cleanup()
print("test_player: ok")
