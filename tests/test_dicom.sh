#!/usr/bin/env bash
# tests/test_dicom.sh - the DICOM format plugin (plugins/dicom, C++ on GDCM) end to end: GDCM
# writes the test series (build/tests/dicom_write: oblique orientation, 5x7 pixels, 3..9 slices
# in shuffled file order, rescale slope/intercept, JPEG-LS, two series in one folder, uneven
# slices, a hostile Rows), then
#   1. the C side (build/tests/test_dicom_load, tests/plugins/dicom_load.c): cdvr_plugin_load and
#      cdvr_volume_load / probe, geometry, values and refusals;
#   2. python3-vtk9's vtkDICOMImageReader reads oblique/ and float/ (skipped without it) and
#      writes its dims, spacing and values for
#   3. the Lua side (tests/lua/dicom_checks.lua through cdvr): cdvr.load(dir), select=, a .dcm
#      file, and VTK's values against cdvr's (VTK's old reader flips y and z).
# Skipped (77) when the plugin is not built (no C++ compiler or no GDCM).
cdvr=${1:?usage: test_dicom.sh path/to/cdvr}
bin=${CDVR_BINARY_DIR:-$(cd "$(dirname "$cdvr")" && pwd)}
src=${CDVR_SOURCE_DIR:-$(cd "$(dirname "$0")/.." && pwd)}
case " ${CDVR_BUILT_PLUGINS-dicom} " in
  *" dicom "*) ;;
  *) echo "skip: the dicom plugin is not built"; exit 77 ;;
esac
[ -x "$bin/tests/dicom_write" ] && [ -x "$bin/tests/test_dicom_load" ] ||
  { echo "FAIL: $bin/tests/dicom_write or test_dicom_load missing"; exit 1; }
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
"$bin/tests/dicom_write" "$tmp" || { echo "FAIL: dicom_write"; exit 1; }
CDVR_BINARY_DIR=$bin "$bin/tests/test_dicom_load" "$tmp" || { echo "FAIL: test_dicom_load"; exit 1; }
python=/usr/bin/python3
if "$python" -c 'import vtk' 2>/dev/null; then
  "$python" - "$tmp" <<'EOF_PY' || { echo "FAIL: python vtk side"; exit 1; }
import sys, vtk
tmp = sys.argv[1]
for case in ("oblique", "float"):
    r = vtk.vtkDICOMImageReader()
    r.SetDirectoryName(tmp + "/" + case)
    r.Update()
    im = r.GetOutput()
    X, Y, Z = im.GetDimensions()
    with open(tmp + "/vtk_" + case + ".txt", "w") as f:
        f.write("%d %d %d %.9g %.9g %.9g\n" % ((X, Y, Z) + im.GetSpacing()))
        for k in range(Z):
            f.write(" ".join(repr(im.GetScalarComponentAsDouble(i, j, k, 0))
                             for j in range(Y) for i in range(X)) + "\n")
EOF_PY
else
  echo "no python3 vtk: the VTK comparison is skipped"
fi
"$cdvr" "$src/tests/lua/dicom_checks.lua" "$tmp" || { echo "FAIL: dicom_checks.lua"; exit 1; }
