-- tests/lua/test_reader_options.lua - the readers' limits from Lua (issue 21 item 4): a detached
-- NRRD header whose data file lies outside its directory is refused by cdvr.load and
-- cdvr.load_series naming the path, and loads with allow_outside=true; max_bytes= refuses a
-- larger claim naming the limit; both options are type-checked. The files are written here.
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check, raises = checks.check, checks.raises

local dir = "test_reader_options_tmp"
os.execute("rm -rf " .. dir .. " && mkdir -p " .. dir .. "/sub")
local function write(name, text)
  local f = assert(io.open(dir .. "/" .. name, "wb"))
  f:write(text)
  f:close()
end
local bytes = {}
for i = 0, 63 do bytes[#bytes + 1] = string.char(i) end
write("outside.raw", table.concat(bytes))
write("sub/up.nhdr", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n" ..
      "data file: ../outside.raw\n")
local hdr = dir .. "/sub/up.nhdr"

raises(function() cdvr.load(hdr) end, "outside.raw) is outside the header's directory",
       "cdvr.load of a data file outside")
raises(function() cdvr.load_series({hdr}) end, "is outside the header's directory",
       "cdvr.load_series of a data file outside")
local v = cdvr.load(hdr, {allow_outside = true})
check(v:get(1, 1, 0) == 5 and v:get(3, 3, 3) == 63, "allow_outside=true loads the named file")
local s = cdvr.load_series({hdr, hdr}, {allow_outside = true})
check(s:timesteps() == 2 and s:frame(2):get(3, 3, 3) == 63, "load_series with allow_outside=true")

raises(function() cdvr.load(hdr, {allow_outside = true, max_bytes = 32}) end,
       "more than max_bytes 32", "max_bytes below the claim")
check(cdvr.load(hdr, {allow_outside = true, max_bytes = 64}):get(1, 0, 0) == 1,
      "max_bytes equal to the claim loads")
raises(function() cdvr.load(hdr, {allow_outside = "yes"}) end,
       "option 'allow_outside': boolean expected, got string", "allow_outside type")
raises(function() cdvr.load(hdr, {max_bytes = 0}) end,
       "option 'max_bytes': positive integer expected", "max_bytes 0")
raises(function() cdvr.load(hdr, {max_bytes = 1.5}) end,
       "option 'max_bytes': positive integer expected", "max_bytes not an integer")

-- the f32 rule (issue 23 item 8): a float64 value beyond f32 is refused unless f32_overflow="inf"
write("big.nrrd", "NRRD0004\ntype: double\ndimension: 3\nsizes: 2 1 1\nendian: little\n" ..
      "encoding: raw\n\n" .. string.pack("<dd", 1e300, -2.5))
local big = dir .. "/big.nrrd"
raises(function() cdvr.load(big) end, 'value 1e+300 (float64, voxel (0,0,0) of timestep 0 from 0) ' ..
       'is beyond the range of f32', "a value beyond f32 refused")
raises(function() cdvr.load_series({big, big}):get(0, 0, 0, 2) end, 'f32_overflow = "inf"',
       "a lazy series refuses too when it reads the frame")
local b = cdvr.load(big, {f32_overflow = "inf"})
check(b:get(0, 0, 0) == math.huge and b:get(1, 0, 0) == -2.5, "f32_overflow=inf: +Inf and the rest")
check(b:info().beyond_f32 == 1 and b:info().source_type == "float64", "v:info().beyond_f32")
check(tostring(b):find("1 values beyond f32 as +-Inf", 1, true), "tostring names it: " .. tostring(b))
raises(function() cdvr.load(big, {f32_overflow = "refuse"}) end, "beyond the range of f32",
       "f32_overflow=refuse is the default")
raises(function() cdvr.load(big, {f32_overflow = true}) end,
       'option \'f32_overflow\': "refuse" or "inf" expected, got true', "f32_overflow type")
check(cdvr.load_series({big, big}, {f32_overflow = "inf"}):get(0, 0, 0, 2) == math.huge,
      "load_series passes f32_overflow to each file")
os.execute("rm -rf " .. dir)
checks.finish()
