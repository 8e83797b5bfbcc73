-- cdvr.path: camera paths (DESIGN.md §7). A path is a callable object:
--
--   p(t)                   -> {eye={x,y,z}, center={x,y,z}, up={x,y,z}, fov=degrees}
--   p:camera(t, w, h [, opts]) -> cdvr.camera{eye=, center=, up=, fov=, width=w, height=h, ...opts}
--   p:totable()            -> plain table ({kind="orbit", ...} / {kind="keyframes", keys={...}})
--   path.from(tbl)         -> path rebuilt from a totable() table
--   path.save(p, file) / path.load(file)   plain Lua files (cdvr.serialize)
--
-- t is whatever unit the user chooses (frame number or seconds); paths only compare it with
-- the times and periods they were given.
--
-- orbit{center=, distance=, up={0,0,1}, elevation=0, start=0, period=, fov=30}
--   The eye turns once around `center` every `period`, counter-clockwise about `up` (right-hand
--   rule), at `elevation` degrees above the plane orthogonal to up; azimuth start + 360 t/period.
--   Azimuth 0 is the world axis least aligned with up, made orthogonal to it (x for up = z),
--   the same convention as cdvr_camera_orbit in core/render/camera.c.
--
-- keyframes{ {time=, eye=, center=, up=, fov=}, ..., loop=false, spline="centripetal",
--            period= }
--   eye and center follow a Catmull-Rom spline through the keys in Hermite form: centripetal
--   knots (alpha = 0.5, no cusps or self-intersections between close keys) by default,
--   spline="uniform" for the uniform one. Within the segment between keys i and i+1 the
--   spline parameter moves linearly with time, so the path is at key i exactly at its time
--   (velocity may change at a key when key spacing in time is uneven). fov is interpolated
--   linearly (it never overshoots the keys' range). up is the normalised linear blend of the
--   two neighbouring keys' up vectors, made orthogonal to the view direction. Before the first
--   key and after the last the path is clamped; end segments use reflected phantom keys.
--   With loop=true the path also runs from the last key back to the first and repeats with
--   `period` (default: last - first time plus their mean spacing). Keys may be given in any
--   order; times must be distinct. up defaults to the previous key's (first: {0,0,1}), fov
--   likewise (first: 30).
--
-- fn(function(t) return {eye=, center=, up=, fov=} end) wraps a Lua function (checked on
--   each call; up and fov default to {0,0,1} and 30). It cannot be saved.
local serialize = require "cdvr.serialize"
local options = require "cdvr.options"

local path = {}

local DEFAULT_UP = { 0, 0, 1 }
local DEFAULT_FOV = 30

-- ---- vectors ------------------------------------------------------------------------------
local function vec(a) return { a[1], a[2], a[3] } end
local function add(a, b) return { a[1] + b[1], a[2] + b[2], a[3] + b[3] } end
local function sub(a, b) return { a[1] - b[1], a[2] - b[2], a[3] - b[3] } end
local function scale(a, s) return { a[1] * s, a[2] * s, a[3] * s } end
local function dot(a, b) return a[1] * b[1] + a[2] * b[2] + a[3] * b[3] end
local function cross(a, b)
  return { a[2] * b[3] - a[3] * b[2], a[3] * b[1] - a[1] * b[3], a[1] * b[2] - a[2] * b[1] }
end
local function norm(a) return math.sqrt(dot(a, a)) end
local function normalize(a)
  local n = norm(a)
  if n == 0 or n ~= n or n == math.huge then return nil end
  return scale(a, 1 / n)
end

-- ---- argument checks ----------------------------------------------------------------------
local function is_finite(x) return type(x) == "number" and x == x and x > -math.huge and x < math.huge end

local function check_vec3(value, what)
  if type(value) ~= "table" or #value ~= 3 then
    error(string.format("%s: 3 numbers expected, got %s", what, type(value) == "table"
      and (#value .. " values") or type(value)), 3)
  end
  for i = 1, 3 do
    if not is_finite(value[i]) then
      error(string.format("%s[%d]: finite number expected, got %s", what, i, tostring(value[i])), 3)
    end
  end
  return vec(value)
end

local function check_number(value, what, default)
  if value == nil and default ~= nil then return default end
  if not is_finite(value) then
    error(string.format("%s: finite number expected, got %s", what, tostring(value)), 3)
  end
  return value
end

local function check_fov(value, what)
  local fov = check_number(value, what)
  if fov <= 0 or fov >= 180 then
    error(string.format("%s: field of view must be in (0, 180) degrees, got %s", what, fov), 3)
  end
  return fov
end

local function check_time(t)
  if type(t) ~= "number" or t ~= t then
    error(string.format("bad argument #1 to 'path' (number expected, got %s)",
                        t ~= t and "nan" or type(t)), 3)
  end
end

-- up made orthogonal to the view direction; nil when parallel to it.
local function orthogonal_up(up, eye, center)
  local f = normalize(sub(center, eye))
  if not f then return nil end
  return normalize(sub(up, scale(f, dot(up, f))))
end

-- ---- the path object ----------------------------------------------------------------------
local Path = { __name = "cdvr.Path" }
Path.__index = {}
local methods = Path.__index

local function new_path(kind, evaluate, state)
  return setmetatable({ kind = kind, evaluate = evaluate, state = state }, Path)
end

function Path.__call(self, t)
  check_time(t)
  return self.evaluate(self.state, t)
end

function Path.__tostring(self)
  return string.format("cdvr.Path (%s)", self.kind)
end

function Path.__tosave(self)
  return self:totable()
end

function methods.camera(self, t, width, height, opts)
  if getmetatable(self) ~= Path then
    error("bad argument #1 to 'camera' (cdvr.Path expected)", 2)
  end
  local view = self(t)
  local cdvr = require "cdvr"
  if type(cdvr.camera) ~= "function" then
    error("path:camera: cdvr.camera is not available in this build", 2)
  end
  local args = {}
  for k, v in pairs(opts or {}) do args[k] = v end
  args.eye, args.center, args.up, args.fov = view.eye, view.center, view.up, view.fov
  args.width, args.height = width, height
  return cdvr.camera(args)
end

function methods.totable(self)
  if getmetatable(self) ~= Path then
    error("bad argument #1 to 'totable' (cdvr.Path expected)", 2)
  end
  if not self.state.totable then
    error(string.format("path:totable: a %s path cannot be saved", self.kind), 2)
  end
  return self.state.totable(self.state)
end

-- ---- orbit --------------------------------------------------------------------------------
-- The world axis least aligned with n, made orthogonal to it (core/render/camera.c's convention).
local function perpendicular(n)
  local axis = 1
  for i = 2, 3 do
    if math.abs(n[i]) < math.abs(n[axis]) then axis = i end
  end
  local e = { 0, 0, 0 }
  e[axis] = 1
  return normalize(sub(e, scale(n, dot(e, n))))
end

local function orbit_eval(o, t)
  local az = math.rad(o.start + 360 * t / o.period)
  local el = math.rad(o.elevation)
  local dir = add(scale(add(scale(o.a, math.cos(az)), scale(o.b, math.sin(az))), math.cos(el)),
                  scale(o.n, math.sin(el)))
  return { eye = add(o.center, scale(dir, o.distance)), center = vec(o.center),
           up = vec(o.n), fov = o.fov }
end

local function orbit_totable(o)
  return { kind = "orbit", center = vec(o.center), distance = o.distance, up = vec(o.up),
           elevation = o.elevation, start = o.start, period = o.period, fov = o.fov }
end

function path.orbit(opts)
  if type(opts) ~= "table" then
    error(string.format("bad argument #1 to 'orbit' (table expected, got %s)", type(opts)), 2)
  end
  options.check(opts, "cdvr.path.orbit", { "center", "distance", "up", "elevation", "start", "period", "fov" })
  local o = {
    center = check_vec3(opts.center, "orbit: center"),
    distance = check_number(opts.distance, "orbit: distance"),
    up = check_vec3(opts.up or DEFAULT_UP, "orbit: up"),
    elevation = check_number(opts.elevation, "orbit: elevation", 0),
    start = check_number(opts.start, "orbit: start", 0),
    period = check_number(opts.period, "orbit: period"),
    fov = check_fov(opts.fov or DEFAULT_FOV, "orbit: fov"),
    totable = orbit_totable,
  }
  if o.distance <= 0 then error("orbit: distance must be > 0", 2) end
  if o.period == 0 then error("orbit: period must not be 0", 2) end
  if math.abs(o.elevation) >= 90 then
    error("orbit: elevation must be in (-90, 90) degrees (up would be along the view)", 2)
  end
  o.n = normalize(o.up)
  if not o.n then error("orbit: up must not be the zero vector", 2) end
  o.a = perpendicular(o.n)
  o.b = cross(o.n, o.a)
  return new_path("orbit", orbit_eval, o)
end

-- ---- keyframes ----------------------------------------------------------------------------
local SPLINE_ALPHA = { centripetal = 0.5, uniform = 0 }

local function check_keys(keys)
  local out = {}
  local up, fov = DEFAULT_UP, DEFAULT_FOV
  for i, key in ipairs(keys) do
    local what = string.format("keyframes: key %d", i)
    if type(key) ~= "table" then
      error(string.format("%s: table expected, got %s", what, type(key)), 3)
    end
    options.check(key, "cdvr.path." .. what, { "time", "eye", "center", "up", "fov" }, 3)
    local k = {
      time = check_number(key.time, what .. " time"),
      eye = check_vec3(key.eye, what .. " eye"),
      center = check_vec3(key.center, what .. " center"),
      up = check_vec3(key.up or up, what .. " up"),
      fov = check_fov(key.fov or fov, what .. " fov"),
    }
    if not orthogonal_up(k.up, k.eye, k.center) then
      error(string.format("%s: eye equals center or up is parallel to the view", what), 3)
    end
    up, fov = k.up, k.fov
    out[i] = k
  end
  if #out == 0 then error("keyframes: at least one key expected", 3) end
  table.sort(out, function(a, b) return a.time < b.time end)
  for i = 2, #out do
    if out[i].time == out[i - 1].time then
      error(string.format("keyframes: two keys at time %s", out[i].time), 3)
    end
  end
  return out
end

-- (b - a) / dtau, or zero when the knot interval is empty (coincident points).
local function chord_rate(a, b, dtau)
  if dtau <= 0 then return { 0, 0, 0 } end
  return scale(sub(b, a), 1 / dtau)
end

-- Hermite-form Catmull-Rom between p1 and p2 at s in [0, 1] (neighbours p0, p3).
local function catmull_rom(p0, p1, p2, p3, s, alpha)
  local d01 = norm(sub(p1, p0)) ^ alpha
  local d12 = norm(sub(p2, p1)) ^ alpha
  local d23 = norm(sub(p3, p2)) ^ alpha
  local m1 = add(sub(chord_rate(p0, p1, d01), chord_rate(p0, p2, d01 + d12)), chord_rate(p1, p2, d12))
  local m2 = add(sub(chord_rate(p1, p2, d12), chord_rate(p1, p3, d12 + d23)), chord_rate(p2, p3, d23))
  m1, m2 = scale(m1, d12), scale(m2, d12)
  local s2, s3 = s * s, s * s * s
  local h00, h10 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s
  local h01, h11 = -2 * s3 + 3 * s2, s3 - s2
  return add(add(scale(p1, h00), scale(m1, h10)), add(scale(p2, h01), scale(m2, h11)))
end

-- Key index with wrap-around (loop) or reflected phantom keys (open path).
local function point(k, keys, i, field)
  local n = #keys
  if k.loop then
    return keys[(i - 1) % n + 1][field]
  elseif i < 1 then
    return sub(scale(keys[1][field], 2), keys[2][field])
  elseif i > n then
    return sub(scale(keys[n][field], 2), keys[n - 1][field])
  end
  return keys[i][field]
end

-- Segment index i (keys i, i+1) and local parameter s for time t.
local function locate(k, t)
  local keys, n = k.keys, #k.keys
  local first = keys[1].time
  if k.loop then
    t = first + (t - first) % k.period
    if t >= keys[n].time then
      return n, (t - keys[n].time) / (first + k.period - keys[n].time)
    end
  elseif t <= first then
    return 1, 0
  elseif t >= keys[n].time then
    return n, 0
  end
  local lo, hi = 1, n       -- keys[lo].time <= t < keys[hi].time
  while hi - lo > 1 do
    local mid = (lo + hi) // 2
    if keys[mid].time <= t then lo = mid else hi = mid end
  end
  return lo, (t - keys[lo].time) / (keys[hi].time - keys[lo].time)
end

local function blend_up(up1, up2, s, eye, center)
  local up = orthogonal_up(add(scale(up1, 1 - s), scale(up2, s)), eye, center)
    or orthogonal_up(s < 0.5 and up1 or up2, eye, center)
    or orthogonal_up(s < 0.5 and up2 or up1, eye, center)
  if up then return up end
  local f = normalize(sub(center, eye))
  if not f then error("keyframes: eye and center coincide between keys", 3) end
  return perpendicular(f)
end

local function keyframes_eval(k, t)
  local keys, n = k.keys, #k.keys
  local i, s = locate(k, t)
  if s == 0 or n == 1 then
    local key = keys[i]
    return { eye = vec(key.eye), center = vec(key.center),
             up = orthogonal_up(key.up, key.eye, key.center), fov = key.fov }
  end
  local j = i % n + 1
  local eye = catmull_rom(point(k, keys, i - 1, "eye"), keys[i].eye, keys[j].eye,
                          point(k, keys, i + 2, "eye"), s, k.alpha)
  local center = catmull_rom(point(k, keys, i - 1, "center"), keys[i].center, keys[j].center,
                             point(k, keys, i + 2, "center"), s, k.alpha)
  return { eye = eye, center = center, up = blend_up(keys[i].up, keys[j].up, s, eye, center),
           fov = keys[i].fov + (keys[j].fov - keys[i].fov) * s }
end

local function keyframes_totable(k)
  local keys = {}
  for i, key in ipairs(k.keys) do
    keys[i] = { time = key.time, eye = vec(key.eye), center = vec(key.center),
                up = vec(key.up), fov = key.fov }
  end
  return { kind = "keyframes", keys = keys, loop = k.loop, spline = k.spline,
           period = k.loop and k.period or nil }
end

function path.keyframes(opts)
  if type(opts) ~= "table" then
    error(string.format("bad argument #1 to 'keyframes' (table expected, got %s)", type(opts)), 2)
  end
  options.check_array(opts, "cdvr.path.keyframes", { "loop", "spline", "period" })
  local spline = opts.spline or "centripetal"
  if not SPLINE_ALPHA[spline] then
    error(string.format("keyframes: spline must be 'centripetal' or 'uniform', got %s",
                        tostring(spline)), 2)
  end
  local k = { keys = check_keys(opts), loop = opts.loop and true or false, spline = spline,
              alpha = SPLINE_ALPHA[spline], totable = keyframes_totable }
  local n = #k.keys
  if k.loop and n >= 2 then
    local span = k.keys[n].time - k.keys[1].time
    k.period = check_number(opts.period, "keyframes: period", span + span / (n - 1))
    if k.period <= span then
      error(string.format("keyframes: period %s must exceed the keys' span %s", k.period, span), 2)
    end
  else
    k.loop = false
  end
  return new_path("keyframes", keyframes_eval, k)
end

-- ---- fn -----------------------------------------------------------------------------------
local function fn_eval(state, t)
  local view = state.fn(t)
  if type(view) ~= "table" then
    error(string.format("path function returned %s, table expected", type(view)), 3)
  end
  local out = {
    eye = check_vec3(view.eye, "path function: eye"),
    center = check_vec3(view.center, "path function: center"),
    up = check_vec3(view.up or DEFAULT_UP, "path function: up"),
    fov = check_fov(view.fov or DEFAULT_FOV, "path function: fov"),
  }
  return out
end

function path.fn(func)
  local mt = getmetatable(func)
  if type(func) ~= "function" and not (type(mt) == "table" and mt.__call) then
    error(string.format("bad argument #1 to 'fn' (function expected, got %s)", type(func)), 2)
  end
  return new_path("fn", fn_eval, { fn = func })
end

-- ---- (de)serialisation --------------------------------------------------------------------
function path.is_path(value)
  return getmetatable(value) == Path
end

function path.from(tbl)
  if type(tbl) ~= "table" then
    error(string.format("bad argument #1 to 'from' (table expected, got %s)", type(tbl)), 2)
  end
  if tbl.kind == "orbit" then
    local opts = {}
    for k, v in pairs(tbl) do
      if k ~= "kind" then opts[k] = v end
    end
    return path.orbit(opts)
  elseif tbl.kind == "keyframes" then
    if type(tbl.keys) ~= "table" then error("path.from: keyframes table without keys", 2) end
    local opts = { loop = tbl.loop, spline = tbl.spline, period = tbl.period }
    for i, key in ipairs(tbl.keys) do opts[i] = key end
    return path.keyframes(opts)
  end
  error(string.format("path.from: unknown path kind %s", tostring(tbl.kind)), 2)
end

function path.save(p, file)
  if getmetatable(p) ~= Path then
    error("bad argument #1 to 'save' (cdvr.Path expected)", 2)
  end
  return serialize.save_lua(p:totable(), file)
end

-- Raises, naming the file and the reason, when the file cannot be read or is not a path (a
-- loader, like cdvr.load and cdvr.tf(path.lua)).
function path.load(file)
  local tbl, err = serialize.load_lua(file)
  if tbl == nil then error("cdvr.path.load: " .. tostring(err):gsub("^load_lua: ", ""), 2) end
  local ok, p = pcall(path.from, tbl)
  if not ok then
    error(string.format("cdvr.path.load: %s: not a camera path: %s", file, p), 2)
  end
  return p
end

return path
