#!/usr/bin/env bash
# CDVR_CL_TILES=0 (cdvr_cl_takes_host_tiles, device.h) keeps every OpenCL frame dense: the
# images of a frame rendered again (tiled and quad copies by default, a dense frame then) are
# byte-identical, unshaded composite and max on neghip (dims 66, not whole tiles) from two
# cameras, one inside the volume; and the player's partial zfp decode (test_decode_cells.lua)
# passes with dense frames too. Skips (77) without OpenCL.
cdvr=${1:?usage: test_cl_layouts.sh path/to/cdvr}
src=${CDVR_SOURCE_DIR:-$(cd "$(dirname "$0")/.." && pwd)}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
"$cdvr" -e 'os.exit(cdvr.cl_info() and 0 or 77)' || { echo "skip: no OpenCL device"; exit 77; }
passed=0; failed=0
check() { local name=$1; shift; if "$@"; then passed=$((passed+1)); else failed=$((failed+1)); echo "FAIL: $name" >&2; fi; }

# each case rendered twice (the second from the device's copies of the frame), then saved
cat >"$tmp/render.lua" <<'LUA'
local out, path = arg[1], arg[2]
local v = assert(cdvr.load(path))
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {40, 0.2, 0.4, 0.9, 0.02}, {120, 1, 0.7, 0.3, 0.3},
                   {255, 1, 1, 1, 0.9}}
local cams = {outside = cdvr.orbit_camera(v, {azimuth = 30, elevation = 20, width = 96, height = 80}),
              inside = cdvr.camera{eye = {30, 33, 36}, center = {60, 10, 20}, up = {0, 0, 1},
                                   fov = 60, width = 96, height = 80}}
local bytes = 0
for name, cam in pairs(cams) do
  for _, blend in ipairs{"composite", "max"} do
    local o = {tf = tf, camera = cam, blend = blend, device = "cl"}
    cdvr.render(v, o)
    local img = cdvr.render(v, o)
    img:save(("%s/%s_%s.png"):format(out, name, blend))
    bytes = math.max(bytes, img:stats().device_bytes)
  end
end
print(bytes) -- the device's buffers: the frame and its copies
LUA
neghip=$src/share/data/neghip_66x66x66_u8.nrrd
mkdir -p "$tmp/copies" "$tmp/dense"
check "render with the device's copies" eval '"$cdvr" "$tmp/render.lua" "$tmp/copies" "$neghip" >"$tmp/copies.bytes"'
check "render dense" eval 'CDVR_CL_TILES=0 "$cdvr" "$tmp/render.lua" "$tmp/dense" "$neghip" >"$tmp/dense.bytes"'
# the copies (tiled: whole 16^3 pages, 80^3 here; quads 4 bytes per tiled voxel) hold more
# than the dense frame (66^3 bytes) and the grids
check "dense frames hold no copies ($(cat "$tmp/dense.bytes") < $(cat "$tmp/copies.bytes") - 512000 bytes)" \
  test "$(cat "$tmp/dense.bytes")" -lt $(( $(cat "$tmp/copies.bytes") - 512000 ))
for f in "$tmp"/copies/*.png; do
  check "$(basename "$f") byte-identical" cmp -s "$f" "$tmp/dense/$(basename "$f")"
done
check "four images" test "$(ls "$tmp"/dense/*.png 2>/dev/null | wc -l)" -eq 4

cells_dense() { # 77: no zfp plugin, the case does not apply
  CDVR_CL_TILES=0 "$cdvr" "$src/tests/lua/test_decode_cells.lua"
  local rc=$?
  [ "$rc" -eq 0 ] || [ "$rc" -eq 77 ]
}
check "partial zfp decode with dense frames" cells_dense
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
