-- tests/lua/test_volume.lua - the Lua volume surface: cdvr.volume/generate/load/load_series,
-- v:get/set/frame/quantize/save_raw/spacing/origin/bytes, #v; I/O failures return nil, msg and
-- misuse raises. Real-data checks use CDVR_SHARED_DATA (exit 77 at the end if it is absent).

local failures = 0
local function check(cond, what)
  if not cond then
    failures = failures + 1
    io.stderr:write("check failed: ", what, "\n", debug.traceback(), "\n")
  end
end

local function raises(f, part, what)
  local ok, msg = pcall(f)
  check(not ok, what .. ": expected an error")
  if not ok and part then
    check(tostring(msg):find(part, 1, true) ~= nil, what .. ": message '" .. tostring(msg) .. "' lacks '" .. part .. "'")
  end
end

local function fails(part, what, v, msg)
  check(v == nil, what .. ": expected nil")
  check(type(msg) == "string" and msg:find(part, 1, true) ~= nil,
        what .. ": message '" .. tostring(msg) .. "' lacks '" .. part .. "'")
end

-- loaders raise (never nil, message): the error names the file and the reason
local function load_raises(part, what, file, f, ...)
  local ok, msg = pcall(f, ...)
  check(not ok, what .. ": expected an error")
  check(not ok and tostring(msg):find(part, 1, true) and tostring(msg):find(file, 1, true),
        what .. ": message '" .. tostring(msg) .. "' lacks '" .. part .. "' or the file " .. file)
end

local TMP = "test_volume_lua_tmp_"

-- cdvr.volume, set/get, frames, #v, bytes
do
  local v = cdvr.volume{dims={3, 2, 2}, type="f32", timesteps=2}
  check(#v == 2 and v:timesteps() == 2 and v:type() == "f32", "volume shape")
  local x, y, z = v:dims()
  check(x == 3 and y == 2 and z == 2, "dims")
  check(v:bytes() == 3 * 2 * 2 * 4 * 2, "bytes")
  local sx, sy, sz = v:spacing()
  local ox, oy, oz = v:origin()
  check(sx == 1 and sy == 1 and sz == 1 and ox == 0 and oy == 0 and oz == 0, "default geometry")
  check(v:get(2, 1, 1) == 0, "zero filled")
  v:set(2, 1, 1, 2, 7.5)
  v:set(0, 0, 0, -1.25)
  check(v:get(2, 1, 1, 2) == 7.5 and v:get(0, 0, 0) == -1.25 and v:get(0, 0, 0, 2) == 0, "set/get with t")
  local f = v:frame(2)
  check(#f == 1 and f:get(2, 1, 1) == 7.5, "frame(2)")
  raises(function() v:frame(3) end, "timestep out of range", "frame(3)")
  raises(function() v:get(3, 0, 0) end, "out of range", "get out of range")
  raises(function() v:set(0, 0, 0, 3, 1) end, "timestep out of range", "set t out of range")
  local lo, hi = v:range()
  check(lo == -1.25 and hi == 7.5, "range")
  check(tostring(v):find("3x2x2 x 2 f32", 1, true), "tostring " .. tostring(v))

  local u = cdvr.volume{dims={2, 1, 1}}
  check(u:type() == "u8", "default type u8")
  raises(function() u:set(0, 0, 0, 256) end, "out of range for u8", "u8 256")
  raises(function() u:set(0, 0, 0, 1.5) end, nil, "u8 1.5")
  raises(function() cdvr.volume{dims={2, 0, 1}} end, "positive integer", "zero dim")
  raises(function() cdvr.volume{dims={2, 1}} end, "3 numbers", "two dims")
  raises(function() cdvr.volume{dims={2, 1, 1}, type="f64"} end, "unknown voxel type", "f64")
  raises(function() cdvr.volume{dims={2^40, 2^40, 2^40}} end, "overflow", "overflowing dims")

  local closed
  do
    local c <close> = cdvr.volume{dims={1, 1, 1}}
    closed = c
  end
  raises(function() closed:dims() end, "closed", "closed volume")
end

-- quantize: window, NaN/Inf counts, default window
do
  local v = cdvr.volume{dims={6, 1, 1}, type="f32"}
  local values = {0 / 0, math.huge, -math.huge, -1, 5, 11}
  for i, x in ipairs(values) do v:set(i - 1, 0, 0, x) end
  local q, r = v:quantize{lo=0, hi=10}
  check(q:type() == "u8", "quantize gives u8")
  local want = {0, 255, 0, 0, 128, 255}
  for i, w in ipairs(want) do check(q:get(i - 1, 0, 0) == w, "quantized voxel " .. i) end
  check(r.nan == 1 and r.inf == 2 and r.clipped_low == 2 and r.clipped_high == 2 and r.clipped == 4,
        "report nan/inf/clipped")
  local d, rd = v:quantize() -- default window = finite range [-1, 11]
  check(d:get(3, 0, 0) == 0 and d:get(5, 0, 0) == 255 and d:get(4, 0, 0) == 128 and rd.clipped == 2, "default window")
  raises(function() v:quantize{lo=3, hi=2} end, "lo <= hi", "hi < lo")
  raises(function() v:quantize{lo="x"} end, "number expected", "lo not a number")
end

-- generate
do
  local ml = cdvr.generate("ml", {dims={41, 41, 41}})
  check(ml:get(20, 20, 20) == 153 and ml:get(20, 20, 40) == 51, "Marschner-Lobb values")
  local b = cdvr.generate("box", {dims={4, 4, 4}, value=9, timesteps=3})
  local lo, hi = b:range()
  check(#b == 3 and lo == 9 and hi == 9, "box")
  local s = cdvr.generate("sphere", {dims={21, 21, 21}, radius=0.5})
  check(s:get(10, 10, 10) == 255 and s:get(15, 10, 10) == 255 and s:get(16, 10, 10) == 0, "sphere")
  local r = cdvr.generate("ramp", {dims={18, 1, 1}, type="f32"})
  check(r:type() == "f32" and r:get(17, 0, 0) == 255 and r:get(0, 0, 0) == 0, "ramp")
  raises(function() cdvr.generate("torus") end, "invalid option", "unknown field")
  raises(function() cdvr.generate("box", {value="high"}) end, "number expected", "bad value")
end

-- raw save/load, endianness, bad files
do
  local v = cdvr.volume{dims={3, 2, 2}, type="i16", timesteps=2}
  for i = 0, 2 do v:set(i, 1, 1, 2, -1000 * i - 7) end
  v:set(1, 0, 0, 300)
  check(v:save_raw(TMP .. "le.raw") == true, "save_raw little")
  check(v:save_raw(TMP .. "be.raw", {endian="big"}) == true, "save_raw big")
  local opts = {dims={3, 2, 2}, type="i16", timesteps=2}
  local le = assert(cdvr.load(TMP .. "le.raw", opts))
  opts.endian = "big"
  opts.spacing = {0.5, 0.5, 2}
  local be = assert(cdvr.load(TMP .. "be.raw", opts))
  local swapped = assert(cdvr.load(TMP .. "le.raw", opts))
  local sx, sy, sz = be:spacing()
  check(sz == 2 and sx == 0.5, "raw spacing option")
  for i = 0, 2 do
    check(le:get(i, 1, 1, 2) == -1000 * i - 7 and be:get(i, 1, 1, 2) == -1000 * i - 7, "raw round trip " .. i)
  end
  check(swapped:get(1, 0, 0) == 11265, "little-endian 300 read as big endian is 0x2c01")

  load_raises("No such file", "missing file", "missing.raw", cdvr.load, TMP .. "missing.raw", {dims={3, 2, 2}, type="u8"})
  load_raises("dims do not match", "size mismatch", "le.raw", cdvr.load, TMP .. "le.raw", {dims={3, 2, 2}, type="u8"})
  load_raises("truncated", "truncated", "le.raw", cdvr.load, TMP .. "le.raw", {dims={3, 2, 2}, type="f32", timesteps=3})
  load_raises("truncated", "header", "le.raw", cdvr.load, TMP .. "le.raw", {dims={3, 2, 2}, type="i16", timesteps=2, header=1})
  load_raises("No such file", "missing nrrd", "missing.nrrd", cdvr.load, TMP .. "missing.nrrd")
  local junk = assert(io.open(TMP .. "junk.nrrd", "w"))
  junk:write("not a nrrd\n")
  junk:close()
  load_raises("cannot read NRRD", "corrupt header", "junk.nrrd", cdvr.load, TMP .. "junk.nrrd")
  fails("No such file", "save into a missing directory", v:save_raw("no_such_dir_lua/x.raw"))

  raises(function() cdvr.load(TMP .. "le.raw") end, "dims and type", "raw without dims")
  raises(function() cdvr.load(TMP .. "le.raw", {dims={3, 2, 2}, type="f64"}) end, "unknown voxel type", "bad type")
  raises(function() cdvr.load(TMP .. "le.raw", {dims={3, 2, 2}, type="u8", endian="middle"}) end, "endian", "bad endian")
  raises(function() cdvr.load(TMP .. "le.raw", {dims={3, 2, 2}, type="u8", header=-1}) end, "header", "negative header")
  raises(function() cdvr.load(TMP .. "le.raw", {dims="big", type="u8"}) end, "table expected", "dims not a table")
  raises(function() cdvr.load(TMP .. "le.raw", {type="u8"}) end, "'dims' is required", "type without dims")
  raises(function() cdvr.load(TMP .. "le.raw", {dims={2^31, 2^31, 2^31}, type="f32", timesteps=2^20}) end,
         "overflow", "absurd dims")
  raises(function() cdvr.load(TMP .. "le.raw", 5) end, "table expected", "opts not a table")
  raises(function() cdvr.load({}) end, "string expected", "path not a string")

  -- series of raw files: a list and a printf pattern
  for t = 1, 3 do
    local f = cdvr.volume{dims={2, 2, 1}, type="u16"}
    f:set(1, 1, 0, 1000 + t)
    f:save_raw(string.format("%sser_%02d.raw", TMP, t))
  end
  local ser = assert(cdvr.load_series({TMP .. "ser_01.raw", TMP .. "ser_03.raw"}, {dims={2, 2, 1}, type="u16"}))
  check(#ser == 2 and ser:get(1, 1, 0, 2) == 1003, "series from a list")
  local pat = assert(cdvr.load_series(TMP .. "ser_%02d.raw", {first=1, count=3, dims={2, 2, 1}, type="u16"}))
  check(#pat == 3 and pat:get(1, 1, 0, 3) == 1003 and pat:get(1, 1, 0, 1) == 1001, "series from a pattern")
  local open = assert(cdvr.load_series(TMP .. "ser_%02d.raw", {first=2, dims={2, 2, 1}, type="u16"}))
  check(#open == 2 and open:get(1, 1, 0, 1) == 1002, "pattern without count takes existing files")
  local last = assert(cdvr.load_series(TMP .. "ser_%02d.raw", {first=1, last=2, dims={2, 2, 1}, type="u16"}))
  check(#last == 2, "pattern with last")
  load_raises("no such file", "pattern without files", "none_0.raw", cdvr.load_series, TMP .. "none_%d.raw", {dims={2, 2, 1}, type="u8"})
  load_raises("No such file", "missing series file", "ser_04.raw",
              cdvr.load_series, TMP .. "ser_%02d.raw", {first=2, count=3, dims={2, 2, 1}, type="u16"})
  raises(function() cdvr.load_series(TMP .. "ser_%s.raw", {count=1}) end, "integer conversion", "%s pattern")
  raises(function() cdvr.load_series(TMP .. "%d_%d.raw", {count=1}) end, "exactly one", "two conversions")
  raises(function() cdvr.load_series(TMP .. "ser.raw", {count=1}) end, "no integer conversion", "no conversion")
  raises(function() cdvr.load_series({}, {}) end, "empty list", "empty list")
  raises(function() cdvr.load_series({TMP .. "ser_01.raw", 7}, {dims={2, 2, 1}, type="u16"}) end,
         "string expected", "list with a number")

  for _, name in ipairs{"le.raw", "be.raw", "junk.nrrd", "ser_01.raw", "ser_02.raw", "ser_03.raw"} do
    os.remove(TMP .. name)
  end
end

-- bundled demo data (share/data)
local source = os.getenv("CDVR_SOURCE_DIR")
if source and source ~= "" then
  local n = assert(cdvr.load(source .. "/share/data/neghip_66x66x66_u8.nrrd"))
  local lo, hi = n:range()
  check(n:type() == "u8" and select(1, n:dims()) == 66 and lo == 0 and hi == 255, "bundled neghip")
  local a = assert(cdvr.load(source .. "/share/data/mpld_asl_64x64x24x25_f32.nii.gz"))
  check(#a == 25 and a:get(32, 32, 12, 1) == 1020, "bundled mpld_asl")
end

-- real data
local data = os.getenv("CDVR_SHARED_DATA")
if data and data ~= "" then
  local h = assert(cdvr.load(data .. "/ct/headsq_64x64x93_u16.nrrd"))
  local sx, sy, sz = h:spacing()
  check(h:type() == "u16" and sx == 3.2 and sy == 3.2 and sz == 1.5 and h:get(32, 32, 46) == 122, "headsq")
  local asl = assert(cdvr.load(data .. "/mri/mpld_asl_64x64x24x25_f32.nii.gz"))
  check(#asl == 25 and asl:type() == "f32" and asl:get(32, 32, 12, 25) == 345, "4D NIfTI is a series")
  check(asl:frame(25):get(32, 32, 12) == 345, "NIfTI frame 25")
  local vf = assert(cdvr.load_series(data .. "/series/viscousfingers/vf_t%03d.nrrd", {first=40, count=3}))
  local x, y, z = vf:dims()
  check(#vf == 3 and x == 64 and y == 64 and z == 64 and vf:type() == "f32", "viscous fingers series")
  local q, r = vf:quantize{lo=0, hi=100}
  check(#q == 3 and r.clipped_high > 0 and r.clipped_low == 0 and r.nan == 0, "series quantize report")
  local _, hi = vf:frame(3):range()
  check(math.abs(hi - 118.8508529663086) < 1e-9, "frame 3 max " .. hi)
  load_raises("No such file", "missing shared file", "nothing.nrrd", cdvr.load, data .. "/ct/nothing.nrrd")
end

if failures > 0 then
  error(failures .. " checks failed")
end
if not data or data == "" then
  print("CDVR_SHARED_DATA not set: real-data checks skipped")
  os.exit(77)
end
print("test_volume.lua: all checks passed")
