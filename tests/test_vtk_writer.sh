#!/usr/bin/env bash
# cdvr's writers (v:save, core/io/write*.c) against VTK's readers: python3-vtk writes one .vti per
# type (u8, u16, i16, f32) of odd dims 11x5x3 (VTK's NRRD reader takes a first axis of 9 or less
# for vector components), a non-zero origin and an oblique direction; cdvr loads each and saves
# it as .vti (raw appended and zlib), .mha (raw and zlib), .mhd, .nrrd (raw and gzip), .nhdr,
# .nii and .nii.gz, and a 2-timestep series (cdvr.load_series of the same file twice, saved by
# reading its timesteps) as a 4D .nii; VTK's vtkXMLImageDataReader, vtkMetaImageReader,
# vtkNrrdReader and vtkNIFTIImageReader read them back and must give the source's dims and every
# voxel value exactly, and where the reader supports it its geometry: .vti origin, spacing and
# direction (1e-12); MetaImage and NRRD origin and spacing (VTK 9.1's readers of these ignore
# the direction); NIfTI the world position of every voxel through the reader's sform and qform
# (1e-4: float32 header fields). Skipped when /usr/bin/python3 has no vtk module.
cdvr=${1:?usage: test_vtk_writer.sh path/to/cdvr}
python=/usr/bin/python3
"$python" -c 'import vtkmodules.vtkIOImage, vtkmodules.vtkIOXML' 2>/dev/null ||
  { echo "skip: no python3 vtk"; exit 77; }
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
# vtkmodules only (not `import vtk`): the parallel module's factory swaps vtkNrrdReader for
# vtkPNrrdReader, which wants an MPI controller.
"$python" - "$tmp" <<'EOF_PY' || { echo "FAIL: python vtk writer side"; exit 1; }
import math, sys
from vtkmodules.vtkCommonCore import VTK_UNSIGNED_CHAR, VTK_UNSIGNED_SHORT, VTK_SHORT, VTK_FLOAT
from vtkmodules.vtkCommonDataModel import vtkImageData
from vtkmodules.vtkIOXML import vtkXMLImageDataWriter
tmp = sys.argv[1]
types = {"u8": VTK_UNSIGNED_CHAR, "u16": VTK_UNSIGNED_SHORT, "i16": VTK_SHORT, "f32": VTK_FLOAT}
def value(t, n):
    return {"u8": (n * 7) % 256, "u16": (n * 977) % 65536, "i16": (n * 131) % 60000 - 30000,
            "f32": 0.25 * n - 7.5}[t]
for t in types:
    im = vtkImageData()
    im.SetExtent(0, 10, 0, 4, 0, 2)
    im.SetOrigin(10, -2, 0.5)
    im.SetSpacing(0.5, 2, 1.25)
    c, s = math.cos(0.7), math.sin(0.7)
    im.SetDirectionMatrix(c, -s, 0, s * 0.6, c * 0.6, -0.8, s * 0.8, c * 0.8, 0.6)
    im.AllocateScalars(types[t], 1)
    a = im.GetPointData().GetScalars()
    for n in range(im.GetNumberOfPoints()):
        a.SetTuple1(n, value(t, n))
    w = vtkXMLImageDataWriter()
    w.SetFileName("%s/src_%s.vti" % (tmp, t))
    w.SetInputData(im)
    assert w.Write() == 1
EOF_PY
cat >"$tmp/save.lua" <<'EOF_LUA'
local tmp = arg[1]
for _, t in ipairs{"u8", "u16", "i16", "f32"} do
  local src = tmp .. "/src_" .. t .. ".vti"
  local v = cdvr.load(src)
  assert(v:type() == t, v:type())
  for _, s in ipairs{".vti", ".mha", ".mhd", ".nrrd", ".nhdr", ".nii", ".nii.gz"} do
    assert(v:save(tmp .. "/out_" .. t .. s))
  end
  for _, s in ipairs{".vti", ".mha", ".nrrd"} do
    assert(v:save(tmp .. "/outz_" .. t .. s, {compress = true}))
  end
  local series = cdvr.load_series({src, src})
  assert(series:save(tmp .. "/out4_" .. t .. ".nii"))
end
EOF_LUA
"$cdvr" "$tmp/save.lua" "$tmp" || { echo "FAIL: cdvr could not save"; exit 1; }
"$python" - "$tmp" <<'EOF_PY'
import sys
from vtkmodules.vtkIOImage import vtkMetaImageReader, vtkNrrdReader, vtkNIFTIImageReader
from vtkmodules.vtkIOXML import vtkXMLImageDataReader
tmp = sys.argv[1]
bad = []
checked = 0
def close(a, b, tol):
    return all(abs(x - y) <= tol * (1 + abs(y)) for x, y in zip(a, b))
def direction(im):
    m = im.GetDirectionMatrix()
    return [m.GetElement(r, c) for r in range(3) for c in range(3)]
for t in ("u8", "u16", "i16", "f32"):
    r = vtkXMLImageDataReader()
    r.SetFileName("%s/src_%s.vti" % (tmp, t))
    r.Update()
    src = r.GetOutput()
    sa = src.GetPointData().GetScalars()
    n = src.GetNumberOfPoints()
    want = [sa.GetTuple1(i) for i in range(n)]
    dims = src.GetDimensions()
    cases = [("out_%s.vti" % t, vtkXMLImageDataReader, "full"),
             ("outz_%s.vti" % t, vtkXMLImageDataReader, "full"),
             ("out_%s.mha" % t, vtkMetaImageReader, "box"),
             ("outz_%s.mha" % t, vtkMetaImageReader, "box"),
             ("out_%s.mhd" % t, vtkMetaImageReader, "box"),
             ("out_%s.nrrd" % t, vtkNrrdReader, "box"),
             ("outz_%s.nrrd" % t, vtkNrrdReader, "box"),
             ("out_%s.nhdr" % t, vtkNrrdReader, "box"),
             ("out_%s.nii" % t, vtkNIFTIImageReader, "nifti"),
             ("out_%s.nii.gz" % t, vtkNIFTIImageReader, "nifti"),
             ("out4_%s.nii" % t, vtkNIFTIImageReader, "nifti4")]
    for name, cls, geo in cases:
        checked += 1
        rd = cls()
        if geo == "nifti4":
            rd.TimeAsVectorOn()
        rd.SetFileName("%s/%s" % (tmp, name))
        rd.Update()
        im = rd.GetOutput()
        a = im.GetPointData().GetScalars()
        if a is None or im.GetDimensions() != dims:
            bad.append("%s: dims %s, want %s" % (name, im.GetDimensions(), dims))
            continue
        comps = 2 if geo == "nifti4" else 1
        if a.GetNumberOfComponents() != comps or a.GetDataTypeAsString() != sa.GetDataTypeAsString():
            bad.append("%s: %d components of %s" % (name, a.GetNumberOfComponents(),
                                                    a.GetDataTypeAsString()))
            continue
        diff = [i for i in range(n) for c in range(comps) if a.GetComponent(i, c) != want[i]]
        if diff:
            i = diff[0]
            bad.append("%s: %d values differ, first at %d: %g, want %g" %
                       (name, len(diff), i, a.GetComponent(i, 0), want[i]))
        if geo == "full" and not (close(im.GetOrigin(), src.GetOrigin(), 1e-12) and
                                  close(im.GetSpacing(), src.GetSpacing(), 1e-12) and
                                  close(direction(im), direction(src), 1e-12)):
            bad.append("%s: geometry %s %s %s" % (name, im.GetOrigin(), im.GetSpacing(), direction(im)))
        if geo == "box" and not (close(im.GetOrigin(), src.GetOrigin(), 1e-12) and
                                 close(im.GetSpacing(), src.GetSpacing(), 1e-12)):
            bad.append("%s: origin %s spacing %s" % (name, im.GetOrigin(), im.GetSpacing()))
        if geo.startswith("nifti"):
            sp = im.GetSpacing()
            for which, m in (("sform", rd.GetSFormMatrix()), ("qform", rd.GetQFormMatrix())):
                if m is None:
                    bad.append("%s: no %s" % (name, which))
                    continue
                worst = 0.0
                for k in range(dims[2]):
                    for j in range(dims[1]):
                        for i in range(dims[0]):
                            p = [0.0, 0.0, 0.0]
                            src.TransformIndexToPhysicalPoint([i, j, k], p)
                            q = m.MultiplyPoint([i * sp[0], j * sp[1], k * sp[2], 1.0])
                            worst = max(worst, max(abs(p[x] - q[x]) for x in range(3)))
                if worst > 1e-4:
                    bad.append("%s: %s world positions off by %g" % (name, which, worst))
for b in bad:
    print("FAIL:", b)
print("%d files read by VTK, %d problems" % (checked, len(bad)))
sys.exit(1 if bad else 0)
EOF_PY
