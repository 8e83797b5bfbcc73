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

os.execute("rm -rf " .. dir)
checks.finish()
