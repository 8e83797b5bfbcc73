-- tests/lua/test_player_stop.lua - playing past the last timestep stops there with a message
-- (report.stopped and a warning line), also when capturing; loop=true wraps around.
local tmpdir = os.tmpname()
os.remove(tmpdir)
assert(os.execute(("mkdir -p %q"):format(tmpdir)))
local vol = cdvr.generate("sphere", {dims = {16, 14, 12}, timesteps = 6})
local st = assert(cdvr.encode(vol, {variants = {{S = 4, T = 3}, {codec = "raw"}}, path = tmpdir .. "/s.cdv",
                                    progress = false}))
local tf = cdvr.tf("hot")
local cam = cdvr.orbit_camera(vol, {width = 24, height = 24})

-- 7 frames of a 6-timestep store: 6 rows, the last at timestep 6, and a message
for _, pipe in ipairs{false, true} do
  local p = cdvr.player{store = st, tf = tf, camera = cam, pipeline = pipe}
  local r = p:run{frames = 7}
  assert(#r.frames == 6, "rows: " .. #r.frames)
  assert(r.frames[6].t == 6, "last row at timestep " .. r.frames[6].t)
  assert(r.stopped and r.stopped:find("last timestep 6", 1, true) and r.stopped:find("6 of 7 frames", 1, true)
         and r.stopped:find("loop=true", 1, true), tostring(r.stopped))
  -- from timestep 4: 3 frames
  r = p:run{frames = 5, first = 4}
  assert(#r.frames == 3 and r.frames[3].t == 6 and r.stopped)
  -- within the series: no message
  r = p:run{frames = 6}
  assert(#r.frames == 6 and r.stopped == nil)
  p:close()
end

-- capture: no frame past the end is written
local cap = cdvr.player{store = st, tf = tf, camera = cam, out = tmpdir .. "/cap/%02d.png"}
local r = cap:run{frames = 8}
assert(#r.frames == 6 and r.stopped)
assert(io.open(tmpdir .. "/cap/06.png"), "frame 6 written")
assert(not io.open(tmpdir .. "/cap/07.png"), "no frame 7: the capture stopped at the last timestep")
cap:close()

-- loop=true: frame 7 shows timestep 1
local lp = cdvr.player{store = st, tf = tf, camera = cam, loop = true}
r = lp:run{frames = 8}
assert(#r.frames == 8 and r.frames[7].t == 1 and r.frames[8].t == 2 and r.stopped == nil)
lp:close()

st:close()
os.execute(("rm -rf %q"):format(tmpdir))
print("test_player_stop: ok")
