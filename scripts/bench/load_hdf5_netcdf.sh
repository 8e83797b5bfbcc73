#!/bin/bash
# scripts/bench/load_hdf5_netcdf.sh - load and probe time of a 256^3 u16 volume as NRRD raw,
# HDF5 contiguous, HDF5 chunked 64^3 + deflate 1 and netCDF-4, formats alternating, 5 repeats,
# medians and the load average (scripts/bench/load_hdf5_netcdf.c). Outside the CMake build:
# compiles against BUILD_DIR/libcdvr_core.a. The files (about 32 MiB each) go to a temporary
# directory, removed at the end. CSV on stdout.
#
#   scripts/bench/load_hdf5_netcdf.sh [BUILD_DIR] [REPS] [N]     (defaults: build, 5, 256)
set -euo pipefail
src=$(cd "$(dirname "$0")/../.." && pwd)
build=$(cd "${1:-$src/build}" && pwd)
reps=${2:-5}
n=${3:-256}
out=$(mktemp -d); trap 'rm -rf "$out"' EXIT
cl_libs=""
if nm "$build/libcdvr_core.a" 2>/dev/null | grep -q " U clGetPlatformIDs"; then cl_libs="-lOpenCL"; fi
gcc -std=c11 -O2 -D_POSIX_C_SOURCE=200809L -I"$src/core/include" $(pkg-config --cflags hdf5-serial netcdf) \
  "$src/scripts/bench/load_hdf5_netcdf.c" "$build/libcdvr_core.a" \
  -lteem -lniftiio -lznz -lexpat -llz4 $(pkg-config --libs libtiff-4 hdf5-serial netcdf) \
  -lz -lbz2 -llzo2 $cl_libs -ldl -lm -lpthread -o "$out/load_hdf5_netcdf"
"$out/load_hdf5_netcdf" "$out" "$reps" "$n"
