#!/bin/bash
# scripts/bench/codec_table.sh - every codec through the codec table on real data (engine CT,
# three viscous-fingers timesteps): bpv, volume PSNR, max error, encode/decode MB/s, decode
# time against memcpy and PVTC S4T3 measured in the same run (scripts/bench/codec_table.c).
# Outside the CMake build: compiles against BUILD_DIR/libcdvr_core.a, loads BUILD_DIR/plugins.
#
#   scripts/bench/codec_table.sh [BUILD_DIR] [REPS]     (defaults: build, 15)   CSV on stdout
set -euo pipefail
src=$(cd "$(dirname "$0")/../.." && pwd)
build=$(cd "${1:-$src/build}" && pwd)
reps=${2:-15}
data=${CDVR_SHARED_DATA:-$src/../shared/data}
out=$(mktemp -d); trap 'rm -rf "$out"' EXIT
cl_libs=""
if nm "$build/libcdvr_core.a" 2>/dev/null | grep -q " U clGetPlatformIDs"; then cl_libs="-lOpenCL"; fi
gcc -std=c11 -O2 -D_POSIX_C_SOURCE=200809L -I"$src/core/include" "$src/scripts/bench/codec_table.c" \
  "$build/libcdvr_core.a" -lteem -lniftiio -lznz -lz -lbz2 -llzo2 $cl_libs -ldl -lm -lpthread -o "$out/codec_table"
"$out/codec_table" "$build/plugins" "$data" "$reps"
