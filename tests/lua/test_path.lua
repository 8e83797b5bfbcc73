-- Camera paths (share/lua/cdvr/path.lua): orbit, keyframes, fn, totable/from, save/load.
local path = require "cdvr.path"
assert(cdvr.path == path, "prelude attaches cdvr.path")

local function dist(a, b)
  return math.sqrt((a[1] - b[1]) ^ 2 + (a[2] - b[2]) ^ 2 + (a[3] - b[3]) ^ 2)
end
local function dot(a, b) return a[1] * b[1] + a[2] * b[2] + a[3] * b[3] end
local function sub(a, b) return { a[1] - b[1], a[2] - b[2], a[3] - b[3] } end
local function close(a, b, tol) return math.abs(a - b) <= tol end

local function expect_error(pattern, f, ...)
  local ok, err = pcall(f, ...)
  assert(not ok, "expected an error matching " .. pattern)
  assert(tostring(err):find(pattern), "error '" .. tostring(err) .. "' does not match " .. pattern)
end

-- ---- orbit ----
do
  local center = { 10, -5, 3 }
  local p = path.orbit{ center = center, distance = 7, elevation = 20, start = 15, period = 36, fov = 40 }
  assert(tostring(p):find("cdvr.Path"))
  for t = -10, 50, 0.75 do
    local view = p(t)
    assert(close(dist(view.eye, center), 7, 1e-9), "eye at the orbit distance")
    assert(dist(view.center, center) == 0 and view.fov == 40)
    -- elevation: the height above the plane orthogonal to up (z) is d*sin(20 deg)
    assert(close(view.eye[3] - center[3], 7 * math.sin(math.rad(20)), 1e-9))
  end
  -- azimuth 0 along +x for up = z, counter-clockwise: a quarter period later along +y
  local q = path.orbit{ center = { 0, 0, 0 }, distance = 2, period = 4 }
  local e0, e1 = q(0).eye, q(1).eye
  assert(close(e0[1], 2, 1e-12) and close(e0[2], 0, 1e-12))
  assert(close(e1[1], 0, 1e-12) and close(e1[2], 2, 1e-12))
  assert(close(dist(q(4).eye, e0), 0, 1e-12), "one turn per period")
  -- other up axes keep the distance and put the eye on the orthogonal plane
  local r = path.orbit{ center = { 1, 2, 3 }, distance = 5, up = { 0, 1, 1 }, period = 10 }
  for t = 0, 10 do
    local view = r(t)
    assert(close(dist(view.eye, { 1, 2, 3 }), 5, 1e-9))
    assert(close(dot(sub(view.eye, { 1, 2, 3 }), { 0, 1, 1 }), 0, 1e-9))
  end
  expect_error("distance must be > 0", path.orbit, { center = { 0, 0, 0 }, distance = 0, period = 1 })
  expect_error("elevation", path.orbit, { center = { 0, 0, 0 }, distance = 1, period = 1, elevation = 90 })
  expect_error("center", path.orbit, { center = { 0, 0 }, distance = 1, period = 1 })
  expect_error("period", path.orbit, { center = { 0, 0, 0 }, distance = 1 })
  expect_error("fov", path.orbit, { center = { 0, 0, 0 }, distance = 1, period = 1, fov = 180 })
  expect_error("number expected", q, "x")
end

-- ---- keyframes ----
local keys = {
  { time = 0, eye = { 4, 0, 1 }, center = { 0, 0, 0 }, up = { 0, 0, 1 }, fov = 30 },
  { time = 2, eye = { 0, 4, 2 }, center = { 0, 0, 0.5 }, fov = 40 },
  { time = 2.5, eye = { -1, 3.9, 2 }, center = { 0, 0, 0.5 }, up = { 0, 0.1, 1 } },
  { time = 6, eye = { -4, 0, 1 }, center = { 1, 0, 0 }, fov = 25 },
  { time = 9, eye = { 0, -4, 0 }, center = { 0, 0, 0 }, up = { 1, 0, 1 } },
}

local function check_keys_hit(p, key_list)
  for _, key in ipairs(key_list) do
    local view = p(key.time)
    for i = 1, 3 do
      assert(view.eye[i] == key.eye[i], "eye passes exactly through the key at its time")
      assert(view.center[i] == key.center[i], "center passes exactly through the key")
    end
  end
end

-- Continuity: small time steps give small moves everywhere, including across key times.
local function check_continuous(p, t0, t1)
  local dt = 1e-3
  local prev = p(t0)
  for t = t0 + dt, t1, dt do
    local view = p(t)
    assert(dist(view.eye, prev.eye) < 0.05, string.format("eye jumps at t=%.3f", t))
    assert(dist(view.center, prev.center) < 0.05, string.format("center jumps at t=%.3f", t))
    assert(dist(view.up, prev.up) < 0.05, string.format("up jumps at t=%.3f", t))
    assert(math.abs(view.fov - prev.fov) < 0.05, string.format("fov jumps at t=%.3f", t))
    prev = view
  end
end

for _, spline in ipairs({ "centripetal", "uniform" }) do
  local opts = { spline = spline }
  for i, k in ipairs(keys) do opts[i] = k end
  local p = path.keyframes(opts)
  check_keys_hit(p, keys)
  check_continuous(p, -1, 10)
  -- fov: linear, inherited by keys without one
  assert(p(1).fov == 35 and p(2.25).fov == 40)
  -- up: unit length and orthogonal to the view everywhere
  for t = -1, 10, 0.1 do
    local view = p(t)
    local f = sub(view.center, view.eye)
    assert(close(dot(view.up, view.up), 1, 1e-9))
    assert(close(dot(view.up, f), 0, 1e-9))
  end
  -- clamped outside the keys
  assert(dist(p(-5).eye, keys[1].eye) == 0 and dist(p(100).eye, keys[5].eye) == 0)
  -- near a key the path approaches it from both sides
  for _, key in ipairs(keys) do
    assert(dist(p(key.time - 1e-7).eye, key.eye) < 1e-5)
    assert(dist(p(key.time + 1e-7).eye, key.eye) < 1e-5)
  end
end

-- Centripetal and uniform differ between keys; two keys give a straight line.
do
  local opts_c, opts_u = { spline = "centripetal" }, { spline = "uniform" }
  for i, k in ipairs(keys) do opts_c[i], opts_u[i] = k, k end
  assert(dist(path.keyframes(opts_c)(4).eye, path.keyframes(opts_u)(4).eye) > 1e-6)
  local line = path.keyframes{ { time = 0, eye = { 0, 0, 0 }, center = { 0, 5, 0 } },
                               { time = 10, eye = { 10, 0, 0 }, center = { 10, 5, 0 } } }
  for t = 0, 10 do
    assert(close(line(t).eye[1], t, 1e-9) and close(line(t).eye[2], 0, 1e-12))
  end
end

-- Repeated points (a camera that pauses) do not produce NaN; keys out of order are sorted.
do
  local p = path.keyframes{
    { time = 3, eye = { 1, 1, 1 }, center = { 0, 0, 0 } },
    { time = 0, eye = { 1, 1, 1 }, center = { 0, 0, 0 } },
    { time = 1, eye = { 1, 1, 1 }, center = { 0, 0, 0 } },
    { time = 2, eye = { 2, 1, 1 }, center = { 0, 0, 0 } },
  }
  for t = 0, 3, 0.01 do
    local e = p(t).eye
    for i = 1, 3 do assert(e[i] == e[i], "no NaN at t=" .. t) end
  end
  assert(dist(p(0.5).eye, { 1, 1, 1 }) < 1e-12, "paused segment stays put")
  check_continuous(p, 0, 3)
end

-- Looping: through the keys, back to the first, periodic.
do
  local square = { loop = true, period = 8,
    { time = 0, eye = { 1, 0, 0 }, center = { 0, 0, 0 } },
    { time = 2, eye = { 0, 1, 0 }, center = { 0, 0, 0 } },
    { time = 4, eye = { -1, 0, 0 }, center = { 0, 0, 0 } },
    { time = 6, eye = { 0, -1, 0 }, center = { 0, 0, 0 } },
  }
  local p = path.keyframes(square)
  check_keys_hit(p, square)
  check_continuous(p, -1, 17)
  assert(dist(p(8).eye, { 1, 0, 0 }) == 0 and dist(p(10).eye, { 0, 1, 0 }) == 0)
  assert(dist(p(7).eye, p(15).eye) < 1e-12 and dist(p(7).eye, p(-1).eye) < 1e-12)
  -- the closing segment is the symmetric image of the others
  assert(close(dist(p(7).eye, { 0, 0, 0 }), dist(p(1).eye, { 0, 0, 0 }), 1e-12))
  expect_error("period", path.keyframes, { loop = true, period = 1,
    { time = 0, eye = { 1, 0, 0 }, center = { 0, 0, 0 } },
    { time = 2, eye = { 0, 1, 0 }, center = { 0, 0, 0 } } })
end

expect_error("two keys at time", path.keyframes, {
  { time = 1, eye = { 1, 0, 0 }, center = { 0, 0, 0 } },
  { time = 1, eye = { 0, 1, 0 }, center = { 0, 0, 0 } } })
expect_error("at least one key", path.keyframes, {})
expect_error("key 1 eye", path.keyframes, { { time = 0, center = { 0, 0, 0 } } })
expect_error("parallel", path.keyframes, { { time = 0, eye = { 0, 0, 1 }, center = { 0, 0, 0 } } })
expect_error("spline", path.keyframes, { spline = "bezier", { time = 0, eye = { 1, 0, 0 }, center = { 0, 0, 0 } } })
-- a single key is a still camera
do
  local still = path.keyframes{ { time = 5, eye = { 1, 0, 0 }, center = { 0, 0, 0 }, fov = 20 } }
  assert(dist(still(-3).eye, { 1, 0, 0 }) == 0 and still(9).fov == 20)
end

-- ---- fn ----
do
  local p = path.fn(function(t) return { eye = { t, 0, 5 }, center = { t, 0, 0 }, up = { 0, 1, 0 } } end)
  local view = p(3)
  assert(view.eye[1] == 3 and view.center[1] == 3 and view.up[2] == 1 and view.fov == 30)
  expect_error("cannot be saved", p.totable, p)
  expect_error("function expected", path.fn, 42)
  expect_error("returned nil", path.fn(function() end), 1)
  expect_error("eye", path.fn(function() return { center = { 0, 0, 0 } } end), 1)
end

-- ---- totable / from / save / load ----
local dir = os.getenv("CDVR_BINARY_DIR") or "."
local function same_path(a, b)
  for t = -2, 12, 0.37 do
    local va, vb = a(t), b(t)
    assert(dist(va.eye, vb.eye) == 0 and dist(va.center, vb.center) == 0)
    assert(dist(va.up, vb.up) == 0 and va.fov == vb.fov)
  end
end
do
  local orbit = path.orbit{ center = { 0.1, 0.2, 0.3 }, distance = 1 / 3, up = { 0, 1, 0 },
                            elevation = -12.5, start = 7, period = 100, fov = 33.3 }
  local tbl = orbit:totable()
  assert(tbl.kind == "orbit" and tbl.distance == 1 / 3 and getmetatable(tbl) == nil)
  same_path(orbit, path.from(tbl))

  local opts = { spline = "uniform" }
  for i, k in ipairs(keys) do opts[i] = k end
  local kf = path.keyframes(opts)
  local ktbl = kf:totable()
  assert(ktbl.kind == "keyframes" and #ktbl.keys == #keys and ktbl.spline == "uniform")
  same_path(kf, path.from(ktbl))

  for _, p in ipairs({ orbit, kf }) do
    local file = dir .. "/test_path_save.lua"
    assert(path.save(p, file))
    local back = assert(path.load(file))
    same_path(p, back)
    -- cdvr.save_lua saves a path through its totable
    assert(cdvr.save_lua({ camera = p }, file))
    local holder = assert(cdvr.load_lua(file))
    same_path(p, path.from(holder.camera))
    os.remove(file)
  end
  local file = dir .. "/test_path_bad.lua"
  local fh = assert(io.open(file, "w"))
  fh:write("return {kind = 'spiral'}\n")
  fh:close()
  local ok, err = pcall(path.load, file)
  assert(not ok and err:find("not a camera path") and err:find("spiral") and err:find(file, 1, true), err)
  os.remove(file)
  ok, err = pcall(path.load, dir .. "/does_not_exist.lua")
  assert(not ok and err:find("does_not_exist"), err)
  expect_error("unknown path kind", path.from, { kind = "spiral" })
end

-- ---- camera (when cdvr.camera has landed) ----
if type(cdvr.camera) == "function" then
  local p = path.orbit{ center = { 0, 0, 0 }, distance = 3, period = 10, fov = 45 }
  local cam = p:camera(2, 64, 48)
  local view = p(2)
  assert(cam.width == 64 and cam.height == 48 and cam.fov == 45)
  assert(dist(cam.eye, view.eye) == 0 and dist(cam.center, view.center) == 0)
  -- the keyframe path's up is orthogonal to the view, so the camera accepts it
  local opts = {}
  for i, k in ipairs(keys) do opts[i] = k end
  local kf = path.keyframes(opts)
  for t = 0, 9, 0.5 do
    local c = kf:camera(t, 32, 32, { orthographic = false })
    assert(dist(c.eye, kf(t).eye) < 1e-12)
  end
else
  local p = path.orbit{ center = { 0, 0, 0 }, distance = 3, period = 10 }
  expect_error("cdvr.camera is not available", p.camera, p, 2, 64, 48)
end

print("test_path: ok")
