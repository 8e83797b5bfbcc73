-- tests/lua/test_hdf5_netcdf.lua - HDF5 and NetCDF files from Lua (core/io/io_hdf5.c,
-- io_netcdf.c): cdvr.load("x.h5:/g/d") and cdvr.load("x.h5", {select = "/g/d"}) give the 4D
-- dataset as a series of 2, voxel for voxel (and cdvr.load_series of two such files, 4), with the group's spacing and the dataset's origin;
-- without a name the file's two 3D/4D datasets are listed; a missing name lists the datasets;
-- NetCDF: "x.nc:u" and select= (series along the unlimited time), a classic file's coordinate
-- variables as spacing/origin/direction, fill values as NaN. The files are written with libhdf5
-- and libnetcdf by the C tests' writers (test_io_hdf5 --write DIR, test_io_netcdf --write DIR in
-- the build directory); skipped (77) when those are not built.
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check, raises_all = checks.check, checks.raises_all

local bin = os.getenv("CDVR_BINARY_DIR") or "."
local function exists(p)
  local f = io.open(p, "rb")
  if f then f:close() end
  return f ~= nil
end
if not exists(bin .. "/test_io_hdf5") or not exists(bin .. "/test_io_netcdf") then
  print("test_io_hdf5 / test_io_netcdf not built in " .. bin .. ": skipped")
  os.exit(77)
end
local dir = os.tmpname()
os.remove(dir)
assert(os.execute("mkdir -p '" .. dir .. "'"))
assert(os.execute("'" .. bin .. "/test_io_hdf5' --write '" .. dir .. "'"))
assert(os.execute("'" .. bin .. "/test_io_netcdf' --write '" .. dir .. "'"))

-- the C writers' values
local function f_h5(i) return 0.25 * i - 7.5 end      -- /g/d: float (t, z, y, x)
local function f_nc(i) return 0.5 * i - 20.25 end     -- u: float (time, z, y, x)
local function s_value(i) return (i * 131) % 2000 - 1000 end

local function series_ok(v, f, what)
  local x, y, z = v:dims()
  check(x == 5 and y == 7 and z == 3 and v:timesteps() == 2 and v:type() == "f32",
        what .. ": dims " .. tostring(x) .. "x" .. tostring(y) .. "x" .. tostring(z))
  local bad = 0
  for t = 1, 2 do
    for k = 0, 2 do
      for j = 0, 6 do
        for i = 0, 4 do
          if v:get(i, j, k, t) ~= f(i + 5 * (j + 7 * (k + 3 * (t - 1)))) then bad = bad + 1 end
        end
      end
    end
  end
  check(bad == 0, what .. ": " .. bad .. " voxels differ")
end

local h5 = dir .. "/lua.h5"
local a = cdvr.load(h5 .. ":/g/d")
series_ok(a, f_h5, "h5 FILE:/g/d")
local sx, sy, sz = a:spacing()
local ox, oy, oz = a:origin()
check(sx == 1.5 and sy == 2.5 and sz == 3.5 and ox == 10 and oy == 20 and oz == 30,
      "h5 spacing/origin attributes")
local x0, x1, y0, y1, z0, z1 = a:bounds()
check(x0 == 10 and x1 == 16 and y0 == 20 and y1 == 35 and z0 == 30 and z1 == 37, "h5 world box")
series_ok(cdvr.load(h5, {select = "/g/d"}), f_h5, "h5 select=/g/d")
local s = cdvr.load_series({h5, h5 .. ":/g/d"}, {select = "/g/d"})
check(s:timesteps() == 4 and s:get(4, 6, 2, 4) == f_h5(209), "h5 load_series with select=")
local o = cdvr.load(h5, {select = "/other"})
check(o:type() == "u8" and o:get(4, 6, 2) == (104 * 7) % 256, "h5 select=/other (chunked u8)")
raises_all(function() cdvr.load(h5) end, {"lua.h5", "3D/4D datasets", "/g/d", "/other"},
           "h5 without a name")
raises_all(function() cdvr.load(h5 .. ":/g/nope") end, {"lua.h5", "no dataset '/g/nope'", "/g/d",
           "/g/flat"}, "h5 missing dataset")
raises_all(function() cdvr.load(h5, {select = "/nope"}) end, {"no dataset '/nope'"},
           "h5 missing select=")
raises_all(function() cdvr.load(h5, {max_bytes = 100}) end, {"lua.h5"}, "h5 max_bytes")

local nc = dir .. "/lua.nc"
series_ok(cdvr.load(nc .. ":u"), f_nc, "nc FILE:u")
series_ok(cdvr.load(nc, {select = "u"}), f_nc, "nc select=u")
local vv = cdvr.load(nc .. ":v")
check(vv:type() == "f32" and vv:get(3, 0, 0) ~= vv:get(3, 0, 0) and
      vv:get(0, 0, 0) == s_value(0) * 0.5 + 10, "nc fill value -> NaN, scale/offset")
raises_all(function() cdvr.load(nc .. ":nope") end, {"lua.nc", "no variable 'nope'", "u(time=2"},
           "nc missing variable")
local c = cdvr.load(dir .. "/lua_classic.nc")
local cx0, cx1, cy0, cy1 = c:bounds()
check(c:type() == "i16" and c:get(4, 6, 2) == s_value(104) and cx0 == 10 and cx1 == 12 and
      cy0 == 88 and cy1 == 100, "classic nc: values and coordinates")

os.execute("rm -rf '" .. dir .. "'")
checks.finish()
