-- Series from a directory, a glob pattern and a .pvd collection (cdvr/series.h, cdvr/pvd.h):
-- cdvr.load_series(dir) and of "dir/t*.nrrd" give natural order (t1, t2, t10); v:times() of a
-- .pvd series gives its timestep values (nil for a directory); tostring(v) and v:info() of a
-- float64 NRRD say it was converted; cdvr.load of a directory no format reads raises naming it.
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check, raises = checks.check, checks.raises

local tmp = os.tmpname()
os.remove(tmp)
assert(os.execute(("mkdir -p %q"):format(tmp)))

local function write(path, data)
  local f = assert(io.open(path, "wb"))
  f:write(data)
  f:close()
end

-- a 2x2x2 uchar NRRD, every voxel v
local function nrrd_u8(path, v)
  write(path, "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n" ..
              string.char(v):rep(8))
end

-- a 2x2x2 ASCII .vti, every value v
local function vti(path, v)
  write(path, ('<?xml version="1.0"?>\n<VTKFile type="ImageData" version="1.0" byte_order="LittleEndian">\n' ..
               '<ImageData WholeExtent="0 1 0 1 0 1" Origin="0 0 0" Spacing="1 1 1">\n' ..
               '<Piece Extent="0 1 0 1 0 1"><PointData Scalars="a">\n' ..
               '<DataArray type="Float32" Name="a" format="ascii">%s</DataArray>\n' ..
               '</PointData><CellData></CellData></Piece></ImageData></VTKFile>\n')
              :format((tostring(v) .. " "):rep(8)))
end

-- directory and glob: natural order
local d = tmp .. "/nat"
assert(os.execute(("mkdir -p %q"):format(d)))
nrrd_u8(d .. "/t10.nrrd", 10)
nrrd_u8(d .. "/t2.nrrd", 2)
nrrd_u8(d .. "/t1.nrrd", 1)
nrrd_u8(d .. "/.hidden.nrrd", 99)
for _, where in ipairs({d, d .. "/t*.nrrd"}) do
  local ok, v = pcall(cdvr.load_series, where)
  check(ok, "load_series " .. where .. ": " .. tostring(v))
  if ok then
    check(v:timesteps() == 3, where .. ": 3 timesteps, got " .. v:timesteps())
    local vals = {v:get(0, 0, 0, 1), v:get(1, 1, 1, 2), v:get(1, 0, 1, 3)}
    check(vals[1] == 1 and vals[2] == 2 and vals[3] == 10,
          where .. ": natural order t1, t2, t10, got " .. table.concat(vals, " "))
    check(v:times() == nil, where .. ": no times")
  end
end

-- .pvd: times kept
local p = tmp .. "/pvd"
assert(os.execute(("mkdir -p %q"):format(p)))
vti(p .. "/a.vti", 3)
vti(p .. "/b.vti", 4)
vti(p .. "/c.vti", 5)
write(p .. "/run.pvd", '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1"><Collection>\n' ..
                       '<DataSet timestep="0.5" part="0" file="a.vti"/>\n' ..
                       '<DataSet timestep="1.5" part="0" file="b.vti"/>\n' ..
                       '<DataSet timestep="2.5" part="0" file="c.vti"/>\n' ..
                       '</Collection></VTKFile>\n')
do
  local ok, v = pcall(cdvr.load_series, p .. "/run.pvd")
  check(ok, "load_series run.pvd: " .. tostring(v))
  if ok then
    local t = v:times()
    check(t and #t == 3 and t[1] == 0.5 and t[2] == 1.5 and t[3] == 2.5,
          "v:times() of the .pvd: " .. (t and table.concat(t, " ") or "nil"))
    local info = v:info()
    check(info.times and info.times[3] == 2.5 and info.files == 3, "v:info() times and files")
    check(v:get(1, 1, 1, 2) == 4, "pvd timestep 2 is b.vti")
  end
end

-- a DataSet outside the collection's directory: refused, read with allow_outside=true
vti(tmp .. "/outside.vti", 7)
write(p .. "/out.pvd", '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1"><Collection>\n' ..
                       '<DataSet timestep="0" part="0" file="../outside.vti"/></Collection></VTKFile>\n')
raises(function() return cdvr.load_series(p .. "/out.pvd") end, "outside.vti", "a .pvd naming ../outside.vti")
do
  local ok, v = pcall(cdvr.load_series, p .. "/out.pvd", {allow_outside = true})
  check(ok and v:get(0, 0, 0, 1) == 7 and v:times()[1] == 0, "allow_outside=true reads it: " .. tostring(v))
end

-- float64: converted
do
  write(tmp .. "/f64.nrrd", "NRRD0004\ntype: double\ndimension: 3\nsizes: 2 1 1\nendian: little\n" ..
                            "encoding: raw\n\n" .. string.pack("<d<d", 0.25, 1e10))
  local v = cdvr.load(tmp .. "/f64.nrrd")
  local s = tostring(v)
  check(s:find("converted from float64", 1, true), "tostring shows the conversion: " .. s)
  local info = v:info()
  check(info.source_type == "float64" and info.converted == true and info.type == "f32",
        "v:info() of a float64 NRRD")
  local u = cdvr.load(d .. "/t1.nrrd")
  check(not tostring(u):find("converted", 1, true) and u:info().converted == false
        and u:info().source_type == "uint8", "a u8 NRRD is not converted: " .. tostring(u))
end

-- a directory no format reads
local plain = tmp .. "/plain_dir"
assert(os.execute(("mkdir -p %q"):format(plain)))
write(plain .. "/notes.txt", "nothing\n")
raises(function() return cdvr.load(plain) end, plain, "cdvr.load(plain directory) names it")
raises(function() return cdvr.load(plain) end, "is a directory that no format reads",
       "cdvr.load(plain directory) says why")

os.execute(("rm -rf %q"):format(tmp))
checks.finish()
