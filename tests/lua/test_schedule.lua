-- Encode-time schedules (share/lua/cdvr/schedule.lua).
local schedule = require "cdvr.schedule"
assert(cdvr.schedule == schedule, "prelude attaches cdvr.schedule")

local function expect_error(pattern, f, ...)
  local ok, err = pcall(f, ...)
  assert(not ok, "expected an error matching " .. pattern)
  assert(tostring(err):find(pattern, 1, true), "error '" .. tostring(err) .. "' does not match " .. pattern)
end

local FAST, SLOW = { S = 1, T = 2 }, { S = 4, T = 3 }
local function is(params, want) return params.S == want.S and params.T == want.T end

-- ---- fixed ----
do
  local s = schedule.fixed{ S = 4, T = 3, pack = "space" }
  for t = 1, 10 do
    local p = s(t)
    assert(p.S == 4 and p.T == 3 and p.pack == "space")
    p.S = 99                              -- callers may modify what they get
  end
  assert(s(1).S == 4)
  assert(math.type(schedule.fixed{ S = 4.0, T = 2 }(1).S) == "integer")
  assert(schedule.fixed{ rate = 0.5 }(3).rate == 0.5, "any codec's parameters")
  expect_error("table of codec parameters expected", schedule.fixed, 4)
  expect_error("parameter names must be strings", schedule.fixed, { 4 })
  expect_error("timestep in 1..", s, 0)
  expect_error("timestep in 1..", s, 1.5)
end

-- ---- quantile ----
do
  local q = schedule.quantile
  assert(q({ 3, 1, 2 }, 0.5) == 2 and q({ 1, 2, 3, 4 }, 0.5) == 2.5)
  assert(q({ 5 }, 0.7) == 5 and q({ 1, 9 }, 0) == 1 and q({ 1, 9 }, 1) == 9)
  assert(q({ 0, 10 }, 0.25) == 2.5 and q({}, 0.5) == nil)
end

-- ---- from_changes ----
do
  -- 10 timesteps, 9 changes; fast motion around timesteps 4-6.
  local changes = { 1, 1, 2, 50, 40, 1, 1, 1, 3 }
  local s, info = schedule.from_changes(changes, { fast = FAST, slow = SLOW, quantile = 0.5 })
  assert(info.threshold == 1 and info.timesteps == 10)
  -- window = max(T) = 3 timesteps -> changes[t], changes[t+1] decide the group at t
  local want = {
    [1] = SLOW,   -- changes 1, 1
    [2] = FAST,   -- 1, 2
    [3] = FAST,   -- 2, 50
    [4] = FAST,   -- 50, 40
    [5] = FAST,   -- 40, 1
    [6] = SLOW,   -- 1, 1
    [7] = SLOW,   -- 1, 1
    [8] = FAST,   -- 1, 3
    [9] = FAST,   -- 3
    [10] = FAST,  -- last timestep: the change leading into it, 3
  }
  for t = 1, 10 do
    assert(is(s(t), want[t]), string.format("t=%d: S=%d T=%d", t, s(t).S, s(t).T))
  end
  expect_error("timestep in 1..10", s, 11)

  -- A higher quantile marks only the fastest part.
  local s90 = schedule.from_changes(changes, { quantile = 0.9 })   -- threshold 42
  for t = 1, 10 do
    assert(is(s90(t), (t == 3 or t == 4) and FAST or SLOW), "quantile 0.9 at t=" .. t)
  end
  -- A uniform series changes nowhere faster than elsewhere: all slow.
  local flat = schedule.from_changes({ 2, 2, 2, 2 })
  for t = 1, 5 do assert(is(flat(t), SLOW)) end
  -- One timestep: no change at all.
  assert(is(schedule.from_changes({})(1), SLOW))
  -- Custom parameter sets pass through, and the window follows their chunk length.
  local custom, cinfo = schedule.from_changes({ 0, 0, 0, 9, 0, 0, 0 },
    { fast = { S = 1, T = 2, pack = "space" }, slow = { S = 4, T = 3, pack = "time" }, quantile = 0.5 })
  assert(cinfo.window == 3, "window: the longer chunk (T3 time; space packing holds 1)")
  assert(is(custom(1), { S = 4, T = 3 }) and custom(1).pack == "time")
  assert(is(custom(2), { S = 4, T = 3 }))             -- changes 2..3: no 9
  assert(is(custom(3), { S = 1, T = 2 }) and custom(3).pack == "space") -- 3..4 include the 9
  assert(is(custom(4), { S = 1, T = 2 }) and is(custom(5), { S = 4, T = 3 }))
  local zfp_ok = pcall(cdvr.codec_chunk, "zfp", { rate = 1 })
  if zfp_ok then                                     -- any codec: zfp holds 1 timestep per chunk
    local z, zinfo = schedule.from_changes({ 0, 9, 0 }, { codec = "zfp", fast = { rate = 4 },
                                                          slow = { rate = 1 } })
    -- one timestep per group: each looks at the change leading into it
    assert(zinfo.window == 1 and z(3).rate == 4 and z(2).rate == 1 and z(1).rate == 1)
  end

  expect_error("changes[2] must be a non-negative number", schedule.from_changes, { 1, 0 / 0 })
  expect_error("changes[1] must be a non-negative number", schedule.from_changes, { -1 })
  expect_error("quantile must be in [0, 1]", schedule.from_changes, { 1 }, { quantile = 2 })
  expect_error("fast: codec pvtc: T = '5', must be 2 or 3", schedule.from_changes, { 1 }, { fast = { T = 5 } })
  expect_error("slow: unknown option 'rate'", schedule.from_changes, { 1 }, { slow = { rate = 2 } })
end

-- ---- change_driven on a synthetic series ----
if type(cdvr.volume) == "function" and type(cdvr.compare) == "function" then
  -- 8 timesteps of 4x4x4 u8; between 3->4 and 4->5 every voxel jumps by 40.
  local v = cdvr.volume{ dims = { 4, 4, 4 }, type = "u8", timesteps = 8 }
  local level = { 10, 11, 12, 52, 92, 93, 94, 95 }
  for t = 1, 8 do
    for z = 0, 3 do for y = 0, 3 do for x = 0, 3 do
      v:set(x, y, z, t, level[t] + ((x + y + z) % 2))
    end end end
  end
  local s, info = schedule.change_driven(v, { quantile = 0.5 })
  assert(#info.changes == 7)
  for t = 1, 7 do
    local step = level[t + 1] - level[t]
    assert(math.abs(info.changes[t] - step * step) < 1e-9, "mse of a uniform step")
  end
  for t = 1, 8 do
    local near_jump = t >= 2 and t <= 4
    assert(is(s(t), near_jump and FAST or SLOW), "change_driven at t=" .. t)
  end
  expect_error("volume expected", schedule.change_driven, 42)
end

-- ---- change_driven on real data (viscous fingering, 6 timesteps) ----
local data = os.getenv("CDVR_SHARED_DATA")
if data and type(cdvr.load_series) == "function" and io.open(data .. "/series/viscousfingers/vf_t040.nrrd") then
  local series = assert(cdvr.load_series(data .. "/series/viscousfingers/vf_t%03d.nrrd",
                                         { first = 40, count = 6 }))
  local q = series:quantize{ lo = 0, hi = 124 }
  local s, info = schedule.change_driven(q, { quantile = 0.5 })
  assert(#info.changes == 5)
  local fast_seen, slow_seen = false, false
  for t = 1, 6 do
    local p = s(t)
    assert(is(p, FAST) or is(p, SLOW))
    fast_seen = fast_seen or is(p, FAST)
    slow_seen = slow_seen or is(p, SLOW)
    assert(info.changes[math.min(t, 5)] >= 0)
  end
  assert(fast_seen and slow_seen, "the median splits a real series into fast and slow parts")
  print(string.format("viscous fingers changes: %s (threshold %.3f)",
                      table.concat(info.changes, " "), info.threshold))
else
  print("test_schedule: shared data absent, real-data part skipped")
end

print("test_schedule: ok")
