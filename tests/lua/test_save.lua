-- tests/lua/test_save.lua - v:save (cdvr/write.h) from Lua: every suffix, compress true/false,
-- a 4D series, a lazy series (cdvr.load_series, saved by reading its timesteps) and a decoded
-- store timestep (st:decode(t):save(...)) round-trip through cdvr.load voxel for voxel with the
-- same geometry; misuse raises naming the option or the file; a target that is a directory
-- returns nil, msg naming it.
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check, raises = checks.check, checks.raises

local dir = os.tmpname()
os.remove(dir)
assert(os.execute("mkdir -p " .. dir))
local function tmp(name) return dir .. "/" .. name end

local function same(a, b, what, tol)
  tol = tol or 1e-12
  local ax, ay, az = a:dims()
  local bx, by, bz = b:dims()
  check(ax == bx and ay == by and az == bz and #a == #b and a:type() == b:type(),
        what .. ": shape " .. ax .. "x" .. ay .. "x" .. az .. " x" .. #a .. " " .. a:type())
  local function near(p, q)
    for i = 1, #p do
      if math.abs(p[i] - q[i]) > tol * (1 + math.abs(q[i])) then return false end
    end
    return true
  end
  check(near({a:spacing()}, {b:spacing()}) and near({a:origin()}, {b:origin()}) and
        near({a:direction()}, {b:direction()}), what .. ": geometry")
  local diff = 0
  for t = 1, #a do
    for z = 0, az - 1 do
      for y = 0, ay - 1 do
        for x = 0, ax - 1 do
          if a:get(x, y, z, t) ~= b:get(x, y, z, t) then diff = diff + 1 end
        end
      end
    end
  end
  check(diff == 0, what .. ": " .. diff .. " voxels differ")
end

local v = cdvr.generate("ml", {dims = {9, 7, 5}, type = "f32"})
for _, s in ipairs{".nrrd", ".nhdr", ".nii", ".nii.gz", ".vti", ".mha", ".mhd"} do
  for _, c in ipairs{false, true} do
    local skip = (s == ".nii" and c) or (s == ".nii.gz" and not c)
    if not skip then
      local p = tmp("v" .. (c and "z" or "") .. s)
      check(v:save(p, {compress = c}) == true, p)
      same(cdvr.load(p), v, p, s:find("nii") and 1e-6 or nil)
    end
  end
  local p = tmp("d" .. s)
  check(v:save(p) == true, p .. " default")
  same(cdvr.load(p), v, p .. " default", s:find("nii") and 1e-6 or nil)
end

-- a 4D series, and a lazy one
local s4 = cdvr.generate("sphere", {dims = {7, 5, 3}, timesteps = 3})
for _, s in ipairs{".nrrd", ".nii.gz", ".mha"} do
  check(s4:save(tmp("s4" .. s)) == true, "4D " .. s)
  same(cdvr.load(tmp("s4" .. s)), s4, "4D " .. s, s:find("nii") and 1e-6 or nil)
end
for t = 1, 3 do assert(s4:frame(t):save(tmp(("f%d.nrrd"):format(t)))) end
local lazy = cdvr.load_series(tmp("f%d.nrrd"), {first = 1, count = 3})
check(lazy:save(tmp("lazy.nrrd")) == true, "lazy series")
same(cdvr.load(tmp("lazy.nrrd")), s4, "lazy series")

-- a series as .vti: numbered files and a .pvd; a .pvd series saved again keeps its times
check(s4:save(tmp("x.vti")) == true, "vti series")
local px = cdvr.load_series(tmp("x.pvd"))
same(cdvr.load(tmp("x.pvd")), s4, "vti series through x.pvd")
check(px:times()[3] == 2, "default times 0, 1, 2")
local pv = io.open(tmp("x.pvd")):read("a")
check(pv:find('file="x_0002.vti"', 1, true), "x.pvd names x_0002.vti")
os.execute("mkdir -p " .. tmp("re"))
check(cdvr.load_series(tmp("x.pvd")):save(tmp("re/y.pvd")) == true, "a .pvd series saved as .pvd")
-- times from a .pvd written by hand survive a save
local f = io.open(tmp("t.pvd"), "w")
f:write('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1"><Collection>\n' ..
        '<DataSet timestep="10.5" part="0" file="x_0000.vti"/>\n' ..
        '<DataSet timestep="20.25" part="0" file="x_0001.vti"/>\n</Collection></VTKFile>\n')
f:close()
check(cdvr.load_series(tmp("t.pvd")):save(tmp("re/t.vti")) == true, "save of a .pvd series")
local tt = cdvr.load_series(tmp("re/t.pvd")):times()
check(tt and tt[1] == 10.5 and tt[2] == 20.25, "times kept through save: " .. tostring(tt and tt[2]))

-- a decoded store timestep
local st = cdvr.encode(s4, {path = tmp("s.cdv"), progress = false})
local d = st:decode(2)
check(d:save(tmp("decoded.nrrd")) == true, "st:decode(2):save")
same(cdvr.load(tmp("decoded.nrrd")), d, "decoded timestep")

-- decoded timesteps saved one file each read back as a lazy series with the store's window
local wlo, whi = st:decode(1):window()
for t = 1, 3 do assert(st:decode(t):save(tmp(("w%d.nrrd"):format(t)))) end
for t = 1, 3 do assert(st:decode(t):save(tmp(("w%d.nii"):format(t)))) end
for _, suffix in ipairs{"nrrd", "nii"} do
  local ws = cdvr.load_series(tmp("w%d." .. suffix), {first = 1, count = 3})
  local lo, hi = ws:window()
  check(ws:info().lazy and lo == wlo and hi == whi,
        ("lazy %s series keeps the saved window: %s %s, saved %s %s"):format(suffix, lo, hi, wlo, whi))
  local elo, ehi = cdvr.load(tmp("w2." .. suffix)):window()
  check(elo == lo and ehi == hi, "lazy and eager window agree (" .. suffix .. ")")
end
check(cdvr.load_series(tmp("w%d.nii"), {first = 1, count = 3}):info().space == "RAS",
      "lazy NIfTI series knows its world (RAS)")

-- misuse raises; I/O failure returns nil, msg
raises(function() v:save(tmp("x.nrrd"), {compres = true}) end, "compres", "unknown option")
raises(function() v:save(tmp("x.png")) end, "x.png", "unknown suffix")
raises(function() v:save(tmp("x.nii"), {compress = true}) end, ".nii.gz", "nii compress")
raises(function() v:save(tmp("x.nrrd"), {compress = "yes"}) end, "compress", "compress type")
assert(os.execute("mkdir -p " .. tmp("dir.nrrd")))
local ok, msg = v:save(tmp("dir.nrrd"))
check(ok == nil and tostring(msg):find("dir.nrrd", 1, true) and msg:find("directory", 1, true),
      "directory target: " .. tostring(msg))

os.execute("rm -rf " .. dir)
checks.finish()
