#!/usr/bin/env bash
# Index-to-world of the real NIfTI files against an independent reading of their headers:
# /usr/bin/python3 parses the 348-byte NIfTI-1 header with struct (no niftilib) and computes
# world = srow * (i, j, k, 1) (sform_code > 0, as in both files) for corner and inner voxels;
# cdvr's v:to_world must agree to 1e-4 mm. The ASL series (share/data) is radiological
# (srow_x = -3.4375 i + 106.97); Colin27 (../shared/data, skipped when absent) is not.
cdvr=${1:?usage: test_orientation.sh path/to/cdvr}
src=${CDVR_SOURCE_DIR:-$(cd "$(dirname "$0")/.." && pwd)}
python=/usr/bin/python3
[ -x "$python" ] || { echo "skip: no $python"; exit 77; }
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
passed=0; failed=0
check() { local name=$1; shift; if "$@"; then passed=$((passed+1)); else failed=$((failed+1)); echo "FAIL: $name" >&2; fi; }

voxels="0,0,0 1,0,0 0,1,0 0,0,1 5,7,3 63,63,23 17,40,11"
compare_file() { # name, path
  local name=$1 path=$2
  "$python" - "$path" "$voxels" >"$tmp/expected" <<'EOF' || return 1
import gzip, struct, sys
path, voxels = sys.argv[1], sys.argv[2]
opener = gzip.open if path.endswith(".gz") else open
h = opener(path, "rb").read(348)
assert struct.unpack("<i", h[0:4])[0] == 348, "not a little-endian NIfTI-1 header"
sform = struct.unpack("<h", h[254:256])[0]
assert sform > 0, "test expects an sform"
srow = [struct.unpack("<4f", h[280 + 16 * r:296 + 16 * r]) for r in range(3)]
for v in voxels.split():
    i, j, k = map(float, v.split(","))
    print(" ".join("%.6f" % (s[0] * i + s[1] * j + s[2] * k + s[3]) for s in srow))
EOF
  cat >"$tmp/world.lua" <<'LUA'
local v = assert(cdvr.load(arg[1]))
for ijk in arg[2]:gmatch("%S+") do
  local i, j, k = ijk:match("(%d+),(%d+),(%d+)")
  print(("%.6f %.6f %.6f"):format(v:to_world(tonumber(i), tonumber(j), tonumber(k))))
end
LUA
  "$cdvr" "$tmp/world.lua" "$path" "$voxels" >"$tmp/got" 2>"$tmp/err" || { cat "$tmp/err" >&2; return 1; }
  paste "$tmp/expected" "$tmp/got" | awk '{ for (c = 1; c <= 3; c++) { d = $c - $(c + 3); if (d < 0) d = -d; if (d > 1e-4) bad = 1 } }
    END { exit bad }' || { echo "$name: expected / got:" >&2; paste "$tmp/expected" "$tmp/got" >&2; return 1; }
}

check "ASL index to world (python struct vs cdvr)" compare_file asl "$src/share/data/mpld_asl_64x64x24x25_f32.nii.gz"
echo 'print(table.concat({cdvr.load(arg[1]):direction()}, " "))' >"$tmp/dir.lua"
asl_dir=$("$cdvr" "$tmp/dir.lua" "$src/share/data/mpld_asl_64x64x24x25_f32.nii.gz")
check "ASL direction is diag(-1, 1, 1)" [ "$asl_dir" = "-1.0 0.0 0.0 0.0 1.0 0.0 0.0 0.0 1.0" ]
if [ -n "$CDVR_SHARED_DATA" ] && [ -f "$CDVR_SHARED_DATA/mri/colin27_t1_301x370x316_u8.nii.gz" ]; then
  voxels="0,0,0 300,369,315 150,185,158 1,2,3"
  check "Colin27 index to world (python struct vs cdvr)" compare_file colin27 "$CDVR_SHARED_DATA/mri/colin27_t1_301x370x316_u8.nii.gz"
fi
echo "$passed passed, $failed failed"
[ $failed -eq 0 ]
