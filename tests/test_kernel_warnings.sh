#!/bin/bash
# tests/test_kernel_warnings.sh CDVR - the OpenCL programs compile without a diagnostic.
# PoCL prints the kernel compiler's warnings ("5 warnings generated.") on the user's terminal
# at every fresh build, so a warning in kernels/ reaches every first run of cdvr. This builds
# the render program (composite, max and iso renders) and hvq's fetch program in an empty
# PoCL and cdvr kernel cache and fails on any "warning" or "error" in the output.
# Skips (77) without an OpenCL device.
set -u
cdvr=${1:?usage: test_kernel_warnings.sh CDVR}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
if [ "$("$cdvr" -e 'print(cdvr.cl_info() ~= nil)')" != true ]; then
  echo "test_kernel_warnings: no OpenCL device: skipped"
  exit 77
fi
export POCL_CACHE_DIR="$tmp/pocl" CDVR_CACHE_DIR="$tmp/cdvr" KW_TMP="$tmp"
"$cdvr" -e '
local v = cdvr.load(cdvr.share_dir .. "/data/neghip_66x66x66_u8.nrrd")
local tf = cdvr.tf{{0, 0, 0, 0, 0}, {60, 0, 0, 0, 0}, {120, 0.9, 0.6, 0.3, 0.5}, {255, 1, 1, 1, 1}}
local cam = cdvr.orbit_camera(v, {azimuth = 30, elevation = 20, width = 32, height = 32})
for _, blend in ipairs{"composite", "max", "iso"} do
  cdvr.render(v, {tf = tf, camera = cam, device = "cl", blend = blend,
                  iso = blend == "iso" and {value = 120} or nil})
end
local path = os.getenv("KW_TMP") .. "/hvq.cdv"
cdvr.render(cdvr.encode(v, {variants = {{codec = "hvq"}}, path = path, progress = false}),
            {tf = tf, camera = cam, device = "cl"})
print("rendered")' >"$tmp/out" 2>&1
status=$?
cat "$tmp/out"
if [ $status -ne 0 ] || ! grep -q '^rendered$' "$tmp/out"; then
  echo "test_kernel_warnings: the renders failed (status $status)"
  echo "0 passed, 1 failed"
  exit 1
fi
if grep -qi 'warning\|error' "$tmp/out"; then
  echo "test_kernel_warnings: a kernel build printed a diagnostic (above)"
  echo "0 passed, 1 failed"
  exit 1
fi
echo "1 passed, 0 failed"
