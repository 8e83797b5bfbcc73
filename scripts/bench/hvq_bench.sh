#!/bin/bash
# scripts/bench/hvq_bench.sh - builds scripts/bench/hvq_bench.c against a built libcdvr_core.a
# (outside the CMake build, like bc1_compare.sh) and runs it; arguments after the build
# directory go to hvq_bench (default: compare on ../shared/data, 3 runs). CSV on stdout.
#
#   scripts/bench/hvq_bench.sh [BUILD_DIR [compare DATADIR RUNS | sweep FILE LABEL K=V,..]]
#   CDVR_PLUGIN_PATH=build/plugins/zfp scripts/bench/hvq_bench.sh build   (adds zfp rows)
set -euo pipefail
src=$(cd "$(dirname "$0")/../.." && pwd)
build=$(cd "${1:-$src/build}" && pwd)
shift || true
data=${CDVR_SHARED_DATA:-$src/../shared/data}
out=${CDVR_BENCH_OUT:-/tmp/cdvr-hvq}
mkdir -p "$out"
cl_libs=""
if nm "$build/libcdvr_core.a" 2>/dev/null | grep -q " U clGetPlatformIDs"; then
  cl_libs="-lOpenCL"
fi
gcc -std=c11 -O2 -D_POSIX_C_SOURCE=200809L -I"$src/core/include" "$src/scripts/bench/hvq_bench.c" \
  "$build/libcdvr_core.a" -lteem -lniftiio -lznz -lz -lbz2 -llzo2 $cl_libs -lm -lpthread -ldl \
  -rdynamic -o "$out/hvq_bench"
if [ $# -eq 0 ]; then
  set -- compare "$data" 3
fi
"$out/hvq_bench" "$@"
