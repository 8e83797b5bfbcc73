#!/usr/bin/env bash
# cdvr's VTK and MetaImage loaders (core/io/io_vti.c, io_vtk.c, io_mha.c) against VTK itself:
# python3-vtk writes .vti files in every mode its writer has (ascii, base64 inline, appended raw
# and base64; no, zlib and LZ4 compression; UInt32 and UInt64 headers), legacy .vtk (ASCII,
# BINARY) and MetaImage (.mhd + .raw, .mha and .mhd + .zraw compressed), of odd dims, an
# extent that does not start at 0, an oblique direction and five scalar types; VTK's own readers
# read them back and give the world position and value of corner and inner voxels; cdvr.load of
# the same file must give the same positions (1e-9) and values (exactly; float64 and int32 as
# the nearest float32). Skipped when /usr/bin/python3 has no vtk module.
cdvr=${1:?usage: test_vtk_reader.sh path/to/cdvr}
python=/usr/bin/python3
"$python" -c 'import vtk' 2>/dev/null || { echo "skip: no python3 vtk"; exit 77; }
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
"$python" - "$tmp" >"$tmp/expected" <<'EOF_PY' || { echo "FAIL: python vtk side"; exit 1; }
import math, struct, sys, vtk
tmp = sys.argv[1]
ext = (3, 9, -2, 2, 1, 3)  # 7 x 5 x 3
types = {"f64": vtk.VTK_DOUBLE, "u16": vtk.VTK_UNSIGNED_SHORT, "i16": vtk.VTK_SHORT,
         "f32": vtk.VTK_FLOAT, "i32": vtk.VTK_INT}
def value(t, n):
    return {"f64": 1e200 * (n - 40) + 0.1 * n, "u16": (n * 977) % 65536,
            "i16": (n * 131) % 60000 - 30000, "f32": 0.25 * n - 7.5,
            "i32": n * 20000001 - 2000000000}[t]
def image(t):
    im = vtk.vtkImageData()
    im.SetExtent(*ext)
    im.SetOrigin(10, -2, 0.5)
    im.SetSpacing(0.5, 2, 1.25)
    c, s = math.cos(0.7), math.sin(0.7)
    im.SetDirectionMatrix(c, -s, 0, s * 0.6, c * 0.6, -0.8, s * 0.8, c * 0.8, 0.6)
    im.AllocateScalars(types[t], 1)
    a = im.GetPointData().GetScalars()
    a.SetName("field")
    for n in range(im.GetNumberOfPoints()):
        a.SetTuple1(n, value(t, n))
    return im
voxels = [(0, 0, 0), (6, 0, 0), (0, 4, 0), (0, 0, 2), (6, 4, 2), (3, 2, 1), (5, 1, 2)]
files = []
i = 0
for t in types:
    for mode, enc, comp, head in [("ascii", 0, "none", 32), ("binary", 0, "none", 32),
                                  ("binary", 0, "zlib", 64), ("appended", 0, "none", 64),
                                  ("appended", 0, "zlib", 32), ("appended", 0, "lz4", 64),
                                  ("appended", 1, "zlib", 32)]:
        path = "%s/f%02d.vti" % (tmp, i); i += 1
        w = vtk.vtkXMLImageDataWriter()
        w.SetFileName(path)
        w.SetInputData(image(t))
        getattr(w, "SetDataModeTo" + mode.capitalize())()
        w.SetEncodeAppendedData(enc)
        {"none": w.SetCompressorTypeToNone, "zlib": w.SetCompressorTypeToZLib,
         "lz4": w.SetCompressorTypeToLZ4}[comp]()
        w.SetHeaderTypeToUInt32() if head == 32 else w.SetHeaderTypeToUInt64()
        assert w.Write() == 1
        files.append((path, t, vtk.vtkXMLImageDataReader()))
    for binary in (0, 1):
        path = "%s/f%02d.vtk" % (tmp, i); i += 1
        w = vtk.vtkStructuredPointsWriter()
        w.SetFileName(path)
        w.SetInputData(image(t))
        w.SetFileTypeToBinary() if binary else w.SetFileTypeToASCII()
        assert w.Write() == 1
        files.append((path, t, vtk.vtkStructuredPointsReader()))
    for suffix, comp in ((".mhd", 0), (".mha", 1), (".mhd", 1)):
        path = "%s/f%02d%s" % (tmp, i, suffix); i += 1
        w = vtk.vtkMetaImageWriter()
        w.SetFileName(path)
        w.SetInputData(image(t))
        w.SetCompression(comp)
        w.Write()
        files.append((path, t, vtk.vtkMetaImageReader()))
for path, t, r in files:
    r.SetFileName(path)
    r.Update()
    im = r.GetOutput()
    e = im.GetExtent()
    for v in voxels:
        ijk = [e[0] + v[0], e[2] + v[1], e[4] + v[2]]
        p = [0.0, 0.0, 0.0]
        im.TransformIndexToPhysicalPoint(ijk, p)
        x = im.GetScalarComponentAsDouble(ijk[0], ijk[1], ijk[2], 0)
        if t in ("f64", "i32"):
            x = struct.unpack("f", struct.pack("f", x))[0] if abs(x) < 3.4e38 else math.copysign(math.inf, x)
        print(path, "%d %d %d" % v, "%.17g %.17g %.17g" % tuple(p), repr(float(x)))
EOF_PY
awk '{print $1, $2, $3, $4}' "$tmp/expected" >"$tmp/list"
cat >"$tmp/got.lua" <<'EOF_LUA'
local list, vols = arg[1], {}
for line in io.lines(list) do
  local path, i, j, k = line:match("(%S+) (%d+) (%d+) (%d+)")
  i, j, k = tonumber(i), tonumber(j), tonumber(k)
  vols[path] = vols[path] or cdvr.load(path, {f32_overflow = "inf"}) -- VTK gives +-Inf too
  local v = vols[path]
  local x, y, z = v:to_world(i, j, k)
  local val = v:get(i, j, k)
  print(string.format("%s %d %d %d %.17g %.17g %.17g %s", path, i, j, k, x, y, z,
                      val == math.huge and "inf" or val == -math.huge and "-inf" or string.format("%.17g", val)))
end
EOF_LUA
"$cdvr" "$tmp/got.lua" "$tmp/list" >"$tmp/got" || { echo "FAIL: cdvr side"; exit 1; }
"$python" - "$tmp/expected" "$tmp/got" <<'EOF_PY'
import sys
exp = [l.split() for l in open(sys.argv[1])]
got = [l.split() for l in open(sys.argv[2])]
bad = 0
assert len(exp) == len(got) and len(exp) > 0, (len(exp), len(got))
for e, g in zip(exp, got):
    pos = max(abs(float(a) - float(b)) for a, b in zip(e[4:7], g[4:7]))
    if e[:4] != g[:4] or pos > 1e-9 or float(e[7]) != float(g[7]):
        bad += 1
        print("FAIL:", " ".join(e), "| cdvr:", " ".join(g[4:]))
print("%d voxels of %d files compared, %d differ" % (len(exp), len(set(x[0] for x in exp)), bad))
sys.exit(1 if bad else 0)
EOF_PY
