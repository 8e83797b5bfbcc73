#!/bin/bash
# scripts/bench/bc1_compare.sh - PVTC <1,3,time> (bbox, lsq) against libsquish BC1 cluster fit
# on the same 4x4 RGB blocks, plus every PVTC variant's bbox/lsq PSNR and the S1T3 decode speed
# against memcpy. Outside the CMake build: needs g++, libsquish-dev and a built libcdvr_core.a.
#
#   scripts/bench/bc1_compare.sh [BUILD_DIR] [OUT_DIR]      (defaults: build, /tmp/cdvr-bc1)
set -euo pipefail
src=$(cd "$(dirname "$0")/../.." && pwd)
build=$(cd "${1:-$src/build}" && pwd)
out=${2:-/tmp/cdvr-bc1}
data=${CDVR_SHARED_DATA:-$src/../shared/data}
mkdir -p "$out"

cl_libs=""
if grep -q "CDVR_HAVE_OPENCL=1\|OpenCL_FOUND:.*=TRUE" "$build/CMakeCache.txt" 2>/dev/null ||
   nm "$build/libcdvr_core.a" 2>/dev/null | grep -q " U clGetPlatformIDs"; then
  cl_libs="-lOpenCL"
fi
gcc -std=c11 -O2 -D_POSIX_C_SOURCE=200809L -I"$src/core/include" "$src/scripts/bench/pvtc_bench.c" \
  "$build/libcdvr_core.a" -lteem -lniftiio -lznz -lz -lbz2 -llzo2 $cl_libs -lm -lpthread -o "$out/pvtc_bench"
g++ -O2 "$src/scripts/bench/bc1_squish.cpp" -lsquish -o "$out/bc1_squish"

"$out/pvtc_bench" prep "$out" "$data"
for set in "vf_u8_64x64x64x60.raw 64 64 64 60" "asl_u8_64x64x24x25.raw 64 64 24 25"; do
  read -r file x y z t <<<"$set"
  echo "== $file: PVTC variants (PSNR over all real voxels, padding excluded)"
  "$out/pvtc_bench" psnr "$out/$file" "$x" "$y" "$z" "$t" | tee "$out/${file%.raw}_pvtc.csv"
  echo "== $file: libsquish BC1 on the same S1T3 blocks"
  "$out/bc1_squish" "$out/$file" "$x" "$y" "$z" "$t" | tee "$out/${file%.raw}_squish.csv"
done
echo "== decode speed (S1T3 time, one 64^3 x 3 chunk, single thread)"
"$out/pvtc_bench" speed "$out/vf_u8_64x64x64x60.raw" 64 64 64 60 15
