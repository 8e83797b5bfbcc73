-- tests/lua/dicom_checks.lua - the DICOM plugin (plugins/dicom) from Lua, on the series that
-- tests/plugins/dicom_write.cpp wrote with GDCM (usage: cdvr dicom_checks.lua DIR; run by
-- tests/test_dicom.sh, which finds the plugin in build/plugins like any cdvr run). Proves:
-- cdvr.formats() lists "dicom" from the plugin; cdvr.load(dir), cdvr.load(dir, {select=UID or
-- description}) and cdvr.load("x.dcm") give the geometry and values the writer put in; two series
-- without select are refused listing both. Where DIR/vtk_CASE.txt exist (python3-vtk9's
-- vtkDICOMImageReader on the same folder, written by test_dicom.sh), VTK's dims and every value
-- match cdvr's voxel (i, R-1-j, S-1-k): VTK's old reader flips rows and slices, ignores the
-- orientation and the position, and reads PixelSpacing's two values as x then y (DICOM gives the
-- row spacing, y, first).
local checks = dofile((arg[0]:match("^(.*)/") or ".") .. "/checks.lua")
local check, raises_all = checks.check, checks.raises_all
local dir = assert(arg[1], "usage: cdvr dicom_checks.lua DIR")

local listed
for _, f in ipairs(cdvr.formats()) do
  if f.name == "dicom" then listed = f end
end
check(listed and listed.plugin and listed.plugin:find("cdvr_dicom.so", 1, true) and
      listed.suffixes[1] == ".dcm", "cdvr.formats() lists the dicom plugin")

local function near(a, b) return math.abs(a - b) <= 1e-6 * (1 + math.abs(b)) end

local function check_oblique(v, what)
  local X, Y, Z = v:dims()
  check(X == 5 and Y == 7 and Z == 9 and v:type() == "i16", what .. ": dims and i16")
  local sx, sy, sz = v:spacing()
  check(near(sx, 0.7) and near(sy, 0.9) and near(sz, 1.3), what .. ": spacing")
  local ox, oy, oz = v:origin()
  check(near(ox, -20.5) and near(oy, 10.25) and near(oz, 30), what .. ": origin")
  local D = {v:direction()}
  local a, b = 0.5, 0.3
  check(near(D[1], math.cos(a)) and near(D[4], math.sin(a)) and near(D[7], 0) and
        near(D[2], -math.sin(a) * math.cos(b)) and near(D[8], math.sin(b)) and
        near(D[9], math.cos(b)),
        what .. ": direction [r c r x c]")
  local bad = 0
  for k = 0, 8 do for y = 0, 6 do for x = 0, 4 do
    if v:get(x, y, k) ~= 2 * ((3 * (x + 5 * y + 35 * k)) % 4096) - 1024 then bad = bad + 1 end
  end end end
  check(bad == 0, what .. ": " .. bad .. " voxels differ")
end

check_oblique(cdvr.load(dir .. "/oblique"), "cdvr.load(dir)")
check_oblique(cdvr.load(dir .. "/oblique/f4.dcm"), "cdvr.load(x.dcm)")
check_oblique(cdvr.load(dir .. "/jpegls"), "JPEG-LS")

raises_all(function() cdvr.load(dir .. "/two") end,
           {"/two: holds 2 DICOM series", "1.2.826.0.1.3680043.9.7777.3 'axial'",
            "1.2.826.0.1.3680043.9.7777.4 'sagittal' 4 slices 6x4x4"}, "two series, no select")
local a = cdvr.load(dir .. "/two", {select = "axial"})
check(select(3, a:dims()) == 3 and a:type() == "u16" and a:get(4, 6, 2) == 100 + 4 + 30 + 70,
      "select= a SeriesDescription")
local s = cdvr.load(dir .. "/two", {select = "1.2.826.0.1.3680043.9.7777.4"})
check(s:dims() == 6 and s:type() == "i16" and s:get(5, 3, 3) == -500 + 35 + 33 + 39,
      "select= a SeriesInstanceUID")
check(cdvr.load(dir .. "/two/s2.dcm"):dims() == 6, "a .dcm file: its own series")
check(cdvr.load(dir .. "/two/f0.dcm"):dims() == 5, "a .dcm file of the other series")
raises_all(function() cdvr.load(dir .. "/two", {select = "coronal"}) end,
           {"no DICOM series 'coronal'", "'axial'", "'sagittal'"}, "unknown select")
raises_all(function() cdvr.load(dir .. "/hostile") end, {"hostile/f1.dcm", "Rows 7000"},
           "hostile Rows")
raises_all(function() cdvr.load(dir .. "/uneven") end, {"uneven slice spacing", "1.5 mm apart"},
           "uneven")

-- VTK's vtkDICOMImageReader on the same folders (files written by test_dicom.sh)
local compared = 0
for _, case in ipairs{"oblique", "float"} do
  local f = io.open(dir .. "/vtk_" .. case .. ".txt")
  if f then
    local X, Y, Z, vsx, vsy, vsz = f:read("n", "n", "n", "n", "n", "n")
    local v = cdvr.load(dir .. "/" .. case)
    local cx, cy, cz = v:dims()
    local sx, sy, sz = v:spacing()
    check(X == cx and Y == cy and Z == cz, case .. ": VTK's dims " .. X .. " " .. Y .. " " .. Z)
    check(math.abs(vsx - sy) < 1e-5 and math.abs(vsy - sx) < 1e-5 and math.abs(vsz - sz) < 1e-4,
          case .. ": VTK's spacing is PixelSpacing in file order (" .. vsx .. " " .. vsy .. ")")
    local bad = 0
    for k = 0, Z - 1 do for j = 0, Y - 1 do for i = 0, X - 1 do
      if f:read("n") ~= v:get(i, Y - 1 - j, Z - 1 - k) then bad = bad + 1 end
    end end end
    f:close()
    check(bad == 0, case .. ": " .. bad .. " voxels differ from VTK's (flipped in y and z)")
    compared = compared + 1
  end
end
-- multi-frame (Enhanced CT), LPS named, and an LPS volume saved as NIfTI lands in RAS
local e = cdvr.load(dir .. "/enhanced")
check_oblique(e, "enhanced/ (frames)")
check(e:info().space == "LPS", "a DICOM volume knows its world: " .. tostring(e:info().space))
local nii = os.tmpname() .. ".nii"
assert(e:save(nii))
local back = cdvr.load(nii)
os.remove(nii)
local ex, ey, ez = e:origin()
local bx, by, bz = back:origin()
check(back:info().space == "RAS" and near(bx, -ex) and near(by, -ey) and near(bz, ez),
      "saved as NIfTI: RAS, x and y negated")
checks.finish(compared > 0 and (" (" .. compared .. " series compared with VTK)") or
              " (VTK comparison skipped)")
