-- tests/lua/test_lazy_series.lua - cdvr.load_series reads its files as it needs them: every
-- method answers as for the same series loaded into memory (dims, type, geometry, #v, bytes,
-- range, window, get, frame, quantize and its report, set, save_raw), cdvr.render{t=} reads one
-- timestep, cdvr.encode streams it into a store identical byte for byte to the one encoded from
-- memory (u8 codes, a float series quantised over its range or over v:quantize's window, 4D
-- files); and files that disappear or change after load_series are errors naming the file.
-- Real data (viscous fingers) when CDVR_SHARED_DATA is set; the rest runs on files made here.

local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check, raises = checks.check, checks.raises_all

local dir = os.tmpname()
os.remove(dir)
assert(os.execute("mkdir -p '" .. dir .. "'"))
local function path(name) return dir .. "/" .. name end

local function read_bytes(p)
  local f = assert(io.open(p, "rb"))
  local s = f:read("a")
  f:close()
  return s
end

-- Files of a float series with NaN, Inf and a value range that grows with t.
local dims, nt = {9, 7, 5}, 4
for t = 1, nt do
  local v = cdvr.volume{dims = dims, type = "f32"}
  for z = 0, dims[3] - 1 do
    for y = 0, dims[2] - 1 do
      for x = 0, dims[1] - 1 do
        v:set(x, y, z, math.sin(x + 2 * y) * 10 * t + z)
      end
    end
  end
  if t == 2 then v:set(1, 1, 1, 0 / 0) end
  if t == 3 then v:set(2, 2, 2, math.huge) end
  v:save_raw(path(("f_%02d.raw"):format(t)))
end
local pattern, opts = path("f_%02d.raw"), {first = 1, count = nt, dims = dims, type = "f32"}
local lazy = cdvr.load_series(pattern, opts)
local eager = cdvr.load_series(pattern, opts)
eager:get(0, 0, 0)          -- a lazy one too: reading all of it makes it an ordinary volume
eager:set(0, 0, 0, 1, eager:get(0, 0, 0, 1))
check(tostring(lazy):find("as needed", 1, true) and not tostring(eager):find("as needed", 1, true),
      "tostring tells a lazy series: " .. tostring(lazy) .. " / " .. tostring(eager))

-- header answers
local a, b = {lazy:dims()}, {eager:dims()}
check(a[1] == 9 and a[2] == 7 and a[3] == 5 and b[3] == 5, "dims")
check(#lazy == nt and lazy:timesteps() == nt and lazy:type() == "f32" and lazy:bytes() == eager:bytes(),
      "timesteps, type, bytes")
check(select(1, lazy:bounds()) == select(1, eager:bounds()), "bounds")

-- values, range, window
local lo, hi = lazy:range()
local elo, ehi = eager:range()
check(lo == elo and hi == ehi, ("range %g %g vs %g %g"):format(lo, hi, elo, ehi))
local wlo, whi = lazy:window()
check(wlo == lo and whi == hi, "window of a float series is its range")
for _, p in ipairs{{0, 0, 0, 1}, {8, 6, 4, 4}, {1, 1, 1, 2}, {2, 2, 2, 3}, {3, 4, 2, 2}} do
  local x, y = lazy:get(p[1], p[2], p[3], p[4]), eager:get(p[1], p[2], p[3], p[4])
  check(x == y or (x ~= x and y ~= y), ("get %d %d %d %d: %s vs %s"):format(p[1], p[2], p[3], p[4], x, y))
end
local f2 = lazy:frame(2, 2)
check(#f2 == 2 and f2:get(4, 3, 2, 2) == eager:get(4, 3, 2, 3), "frame(t, count)")
local fw = {f2:window()}
check(fw[1] == lo and fw[2] == hi, "a frame keeps the series' window")
raises(function() lazy:get(9, 0, 0) end, {"out of range"}, "coordinate out of range")
raises(function() lazy:frame(4, 2) end, {"out of range"}, "count out of range")

-- quantize: a lazy u8 series; its report counts when read
local q, rep = lazy:quantize{lo = -5, hi = 20}
local eq, erep = eager:quantize{lo = -5, hi = 20}
check(q:type() == "u8" and tostring(q):find("as needed", 1, true), "quantize of a lazy series is lazy")
check(q:get(3, 4, 2, 2) == eq:get(3, 4, 2, 2) and q:get(1, 1, 1, 2) == eq:get(1, 1, 1, 2), "codes")
check(rep.clipped == erep.clipped and rep.nan == erep.nan and rep.inf == erep.inf and
      rep.clipped_low == erep.clipped_low and rep.clipped_high == erep.clipped_high,
      ("report %d/%d/%d vs %d/%d/%d"):format(rep.clipped, rep.nan, rep.inf, erep.clipped, erep.nan, erep.inf))
local qw = {q:window()}
check(qw[1] == -5 and qw[2] == 20, "quantize window")
local qlo, qhi = q:range()
local eqlo, eqhi = eq:range()
check(qlo == eqlo and qhi == eqhi, "range of the codes")
local qd = lazy:quantize()
check(select(2, qd:window()) == hi, "default window: the range")

-- rendering one timestep reads that timestep only, and draws what the volume in memory draws
local tf = cdvr.tf{{-5, 0, 0, 0, 0}, {20, 1, 0.8, 0.5, 0.6}, {45, 1, 1, 1, 0.9}}
local cam = cdvr.camera{eye = {30, -20, 25}, center = {4, 3, 2}, up = {0, 0, 1}, fov = 30, width = 40, height = 32}
local ia = cdvr.render(lazy, {tf = tf, camera = cam, t = 3})
local ib = cdvr.render(eager, {tf = tf, camera = cam, t = 3})
check(cdvr.compare(ia, ib).mse == 0, "render{t=} of the lazy series")

-- encode: the same store, byte for byte, as from memory; a series quantised lazily records
-- the type it had before (f32) where the u8 volume in memory can only say u8, so those two
-- stores are compared field by field and chunk by chunk
local function same_store(vol_a, vol_b, name, spec, source_type)
  spec = spec or {}
  spec.progress = false
  spec.path = path(name .. "_a.cdv")
  local sa = cdvr.encode(vol_a, spec)
  spec.path = path(name .. "_b.cdv")
  local sb = cdvr.encode(vol_b, spec)
  if not source_type then
    check(read_bytes(path(name .. "_a.cdv")) == read_bytes(path(name .. "_b.cdv")), name .. ": stores differ")
  else
    local ia, ib = sa:info(), sb:info()
    check(ia.source_type == source_type and ia.window[1] == ib.window[1] and ia.window[2] == ib.window[2],
          name .. ": source type " .. tostring(ia.source_type) .. " and window")
    for v = 1, #ia.variants do
      check(ia.variants[v].psnr == ib.variants[v].psnr and ia.variants[v].chunks == ib.variants[v].chunks,
            name .. ": variant " .. v)
      for c = 1, ia.variants[v].chunks do
        check(sa:chunk(c, v) == sb:chunk(c, v), name .. ": chunk " .. c .. " of variant " .. v)
      end
    end
  end
  sa:close()
  sb:close()
end
same_store(lazy, eager, "float", {S = 1, T = 3})          -- quantised over the series' range
same_store(q, eq, "quantized", {S = 4, T = 2, pack = "space", threads = 2}, "f32")
-- a u8 series of 4D raw files (two timesteps each)
for k = 1, 3 do
  local v = cdvr.volume{dims = {6, 5, 4}, type = "u8", timesteps = 2}
  for t = 1, 2 do
    for i = 0, 5 do v:set(i, i % 5, i % 4, t, (k * 40 + t * 9 + i * 17) % 256) end
  end
  v:save_raw(path(("u_%d.raw"):format(k)))
end
local uopts = {first = 1, count = 3, dims = {6, 5, 4}, type = "u8", timesteps = 2}
local u, ue = cdvr.load_series(path("u_%d.raw"), uopts), cdvr.load_series(path("u_%d.raw"), uopts)
ue:get(0, 0, 0)
ue:set(0, 0, 0, 1, ue:get(0, 0, 0, 1)) -- into memory
check(#u == 6 and u:get(3, 3, 3, 5) == ue:get(3, 3, 3, 5), "4D files: timesteps concatenated")
same_store(u, ue, "u8", {variants = {{codec = "raw"}, {S = 4, T = 3}}})

-- set and save_raw need every voxel: the series is read into memory once, then as before
local s2 = cdvr.load_series(pattern, opts)
s2:set(0, 0, 0, 2, 42.5)
check(s2:get(0, 0, 0, 2) == 42.5 and not tostring(s2):find("as needed", 1, true), "set")
check(s2:save_raw(path("all.raw")) == true and #read_bytes(path("all.raw")) == 9 * 7 * 5 * 4 * nt,
      "save_raw")

-- files that go away or change after load_series: errors name the file
local gone = cdvr.load_series(pattern, opts)
os.remove(path("f_04.raw"))
raises(function() gone:get(0, 0, 0, 4) end, {"f_04.raw"}, "deleted file")
check(gone:get(0, 0, 0, 1) == eager:get(0, 0, 0, 1), "the other files still read")
raises(function() cdvr.encode(gone, {path = path("gone.cdv"), progress = false}) end, {"f_04.raw"},
       "encode of a series whose file went away")
local fh = assert(io.open(path("f_04.raw"), "wb"))
fh:write(("\0"):rep(16))
fh:close()
raises(function() gone:get(0, 0, 0, 4) end, {"f_04.raw"}, "file of another size")
raises(function() cdvr.load_series(pattern, opts) end, {"f_04.raw"}, "load_series checks every file")

-- real data: viscous fingers, lazy against in memory
local data = os.getenv("CDVR_SHARED_DATA")
if data then
  local vp, vo = data .. "/series/viscousfingers/vf_t%03d.nrrd", {first = 60, count = 4}
  local vl, vm = cdvr.load_series(vp, vo), cdvr.load_series(vp, vo)
  vm:set(0, 0, 0, 1, vm:get(0, 0, 0, 1))
  local l1, h1 = vl:range()
  local l2, h2 = vm:range()
  check(l1 == l2 and h1 == h2, "viscous fingers range")
  same_store(vl, vm, "vf", {S = 4, T = 3})
  same_store(vl:quantize{lo = 0, hi = 125}, vm:quantize{lo = 0, hi = 125}, "vfq", {S = 1, T = 3}, "f32")
end

os.execute("rm -rf '" .. dir .. "'")
checks.finish()
if not data then os.exit(77) end
