-- tests/lua/test_formats.lua - file formats from Lua (cdvr/format.h): cdvr.formats() lists the
-- built-ins with their suffixes; an unknown file is refused naming it and the formats known;
-- the example format plugin (plugins/format_example, when built) loads with cdvr.plugin.load,
-- which names what it registered, and cdvr.load / cdvr.load_series then open its files.
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check, raises_all = checks.check, checks.raises_all

local by = {}
for i, f in ipairs(cdvr.formats()) do
  f.index = i
  by[f.name] = f
end
check(by.nrrd and by.nrrd.index == 1 and by.nrrd.magic and by.nrrd.suffixes[2] == ".nhdr" and
      not by.nrrd.plugin, "nrrd listed first, with its suffixes and magic")
check(by.nifti and by.nifti.suffixes[2] == ".nii.gz", "nifti")
check(by.raw and by.raw.described and not by.raw.magic, "raw: described, no magic")

local dir = os.tmpname()
os.remove(dir)
assert(os.execute("mkdir -p '" .. dir .. "'"))
local function write(name, text)
  local f = assert(io.open(dir .. "/" .. name, "wb"))
  f:write(text)
  f:close()
  return dir .. "/" .. name
end

local junk = write("junk.xyz", "not a volume\n")
raises_all(function() cdvr.load(junk) end,
           {junk, "unknown file type", "nrrd (.nrrd .nhdr)", "nifti (.nii .nii.gz .hdr)",
            "raw (.raw .bin .dat, with dims and type)"}, "unknown file")

local built = " " .. (os.getenv("CDVR_BUILT_PLUGINS") or "") .. " "
local bin = os.getenv("CDVR_BINARY_DIR") or "."
if built:find(" format_example ", 1, true) then
  local name, what = cdvr.plugin.load(bin .. "/plugins/cdvr_format_example.so")
  check(name == "cvol" and #what.codecs == 0 and what.formats[1] == "cvol" and
        what.formats[2] == "cvls", "plugin.load names its formats: " .. tostring(name))
  local listed = {}
  for _, f in ipairs(cdvr.formats()) do listed[f.name] = f end
  check(listed.cvol and listed.cvol.plugin and listed.cvol.plugin:find("cdvr_format_example.so", 1, true)
        and listed.cvls.series, "cdvr.formats() shows the plugin's formats")
  local v = cdvr.load(write("a.cvol", "CVOL1\ndims 2 2 1\ntype u8\n\n\1\2\3\4"))
  check(v:dims() == 2 and v:get(1, 1, 0) == 4 and v:type() == "u8", "cdvr.load of a .cvol")
  write("b", "CVOL1\ndims 2 2 1\ntype u8\n\n\5\6\7\8")
  local s = cdvr.load_series{write("ab.cvls", "CVLS1\na.cvol\nb\n")}
  check(s:timesteps() == 2 and s:get(0, 0, 0, 2) == 5, "cdvr.load_series of a .cvls list")
  raises_all(function() cdvr.load(dir .. "/ab.cvls") end, {"ab.cvls", "open it as a series"},
             "a list alone")
else
  print("plugin format_example not built: its cases are skipped")
end
os.execute("rm -rf '" .. dir .. "'")
checks.finish()
