#!/usr/bin/env bash
# The OpenCL frame layout (cdvr_cl_info.dense_frames, device.h): CDVR_CL_TILES=0 keeps every
# frame dense, =1 makes the tiled copies (the test environment's setting). The images of a
# frame rendered again (from the tiled and quad copies, or from the dense frame) are
# byte-identical: unshaded composite and max on neghip (dims 66, not whole tiles) from two
# cameras, one inside the volume, and shaded composite (which casts from the tiled and
# gradient copies in either layout). The player's partial zfp decode (test_decode_cells.lua)
# passes with dense frames too. Without the variable cdvr_cl_open measures the layouts once
# and remembers its choice. Skips (77) without OpenCL.
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
-- shaded last: its copies stay on the device's stream, which every case shares
for _, blend in ipairs{"composite", "max", "shaded"} do
  for name, cam in pairs(cams) do
    local o = {tf = tf, camera = cam, blend = blend == "shaded" and "composite" or blend,
               shade = blend == "shaded", device = "cl"}
    cdvr.render(v, o)
    local img = cdvr.render(v, o)
    img:save(("%s/%s_%s.png"):format(out, name, blend))
    if blend ~= "shaded" then bytes = math.max(bytes, img:stats().device_bytes) end
  end
end
print(bytes) -- the device's buffers of the unshaded cases: the frame and its copies
LUA
neghip=$src/share/data/neghip_66x66x66_u8.nrrd
mkdir -p "$tmp/copies" "$tmp/dense"
check "render with the device's copies" eval 'CDVR_CL_TILES=1 "$cdvr" "$tmp/render.lua" "$tmp/copies" "$neghip" >"$tmp/copies.bytes"'
check "render dense" eval 'CDVR_CL_TILES=0 "$cdvr" "$tmp/render.lua" "$tmp/dense" "$neghip" >"$tmp/dense.bytes"'
# the copies (tiled: whole 16^3 pages, 80^3 here; quads 4 bytes per tiled voxel) hold more
# than the dense frame (66^3 bytes) and the grids
check "dense frames hold no copies ($(cat "$tmp/dense.bytes") < $(cat "$tmp/copies.bytes") - 512000 bytes)" \
  test "$(cat "$tmp/dense.bytes")" -lt $(( $(cat "$tmp/copies.bytes") - 512000 ))
for f in "$tmp"/copies/*.png; do
  check "$(basename "$f") byte-identical" cmp -s "$f" "$tmp/dense/$(basename "$f")"
done
check "six images" test "$(ls "$tmp"/dense/*.png 2>/dev/null | wc -l)" -eq 6

cells_dense() { # 77: no zfp plugin, the case does not apply
  CDVR_CL_TILES=0 "$cdvr" "$src/tests/lua/test_decode_cells.lua"
  local rc=$?
  [ "$rc" -eq 0 ] || [ "$rc" -eq 77 ]
}
check "partial zfp decode with dense frames" cells_dense
# the measured choice (cdvr_cl_open, without CDVR_CL_TILES): made once into a fresh cache
# directory, then read back from it; dense exactly where it cast below CDVR_CL_DENSE_SHARE
# (1.0) of the tiled time
cat >"$tmp/layout.lua" <<'LUA'
local i = assert(cdvr.cl_info())
print(("%s %.17g %.17g %d %.17g %.17g %d"):format(i.frames, i.layout_dense_ms, i.layout_tiled_ms,
                                                 i.quads_max_bytes, i.quads_base_ms, i.quads_ms,
                                                 i.still_quads and 1 or 0))
LUA
first=$(env -u CDVR_CL_TILES CDVR_CACHE_DIR="$tmp/cache" "$cdvr" "$tmp/layout.lua")
again=$(env -u CDVR_CL_TILES CDVR_CACHE_DIR="$tmp/cache" "$cdvr" "$tmp/layout.lua")
echo "layout: $first"
# and the quad copy's limit (device.h, CDVR_CL_QUADS_SHARE 0.95): 256 MB exactly where the
# probe's quad casts took below 0.95 of its casts without (the tiled copy, or dense frames),
# else 64 MB; with dense frames that also keeps the copies of frames rendered again
# (still_quads)
small=$((64 << 20)); large=$((256 << 20))
measured() { # frames dense_ms tiled_ms quads_max quads_base_ms quads_ms still_quads
  awk -v f="$1" -v d="$2" -v t="$3" -v q="$4" -v qt="$5" -v qq="$6" -v sq="$7" -v s=$small \
      -v l=$large \
    'BEGIN { ok = d > 0 && t > 0 && ((f == "dense") == (d < 1.0 * t)) &&
                  (f == "dense" || f == "tiled") && qt > 0 && qq > 0 &&
                  q == (qq < 0.95 * qt ? l : s) && sq == (f == "dense" && q == l);
             exit !ok }'
}
check "measured once ($first)" measured $first
same_record() { # the second run read the first one's records (times to their 4 decimals)
  echo "$first $again" | awk '{ exit !($1 == $8 && ($2 - $9) ^ 2 < 1e-6 && ($3 - $10) ^ 2 < 1e-6 &&
                                     $4 == $11 && ($5 - $12) ^ 2 < 1e-6 && ($6 - $13) ^ 2 < 1e-6 &&
                                     $7 == $14) }'
}
check "remembered: the same choices and times ($again)" same_record
check "one layout record in the cache" test "$(ls "$tmp"/cache/*.layout 2>/dev/null | wc -l)" -eq 1
quads_records=$(ls "$tmp"/cache/*.quads 2>/dev/null | wc -l)
check "one quad record in the cache" test "$quads_records" -eq 1
check "CDVR_CL_TILES=0 overrides, nothing measured" test "$(CDVR_CL_TILES=0 CDVR_CACHE_DIR="$tmp/cache2" "$cdvr" "$tmp/layout.lua")" = "dense 0 0 $small 0 0 0"
check "CDVR_CL_TILES=1 overrides, no quads measured" test "$(CDVR_CL_TILES=1 CDVR_CACHE_DIR="$tmp/cache2" "$cdvr" "$tmp/layout.lua")" = "tiled 0 0 $small 0 0 0"
check "CDVR_CL_QUADS set: no quads measured" eval 'CDVR_CL_QUADS=1 CDVR_CACHE_DIR="$tmp/cache3" "$cdvr" "$tmp/layout.lua" | grep -q " $small 0 0 0\$"'
check "nothing recorded for them" test "$(ls "$tmp"/cache2 "$tmp"/cache3 2>/dev/null | grep -c '\.quads$')" -eq 0
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
