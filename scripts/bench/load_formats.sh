#!/bin/bash
# scripts/bench/load_formats.sh - load and probe speed of the exchange formats cdvr writes
# (scripts/bench/load_formats.c: a 256^3 u16 volume saved as NRRD raw/gzip, NIfTI/.nii.gz, VTI
# raw/zlib, MHA raw/zlib and multi-page TIFF raw/deflate, loaded and probed in rotated order,
# medians, MB/s, ratio to NRRD raw, load average). A C program rather than Lua: the header probe
# (cdvr_volume_probe) has no Lua binding, and the TIFF is written with libtiff's C API.
# Outside the CMake build: compiles against BUILD_DIR/libcdvr_core.a with the flags and libraries
# CMake linked the tests with (so a sanitizer build works too).
#
#   scripts/bench/load_formats.sh [BUILD_DIR] [N] [REPS]     (defaults: build, 256, 5)
set -euo pipefail
src=$(cd "$(dirname "$0")/../.." && pwd)
build=$(cd "${1:-$src/build}" && pwd)
n=${2:-256}
reps=${3:-5}
link="$build/CMakeFiles/test_io_write.dir/link.txt"
[ -f "$link" ] || { echo "load_formats.sh: $link missing: build cdvr first" >&2; exit 1; }
libs=$(sed -e 's/.* -o test_io_write //' -e "s#libcdvr_core.a#$build/libcdvr_core.a#" "$link")
flags=$(sed -e 's# CMakeFiles/.*##' -e 's#^[^ ]* ##' "$link") # the build's link flags (-fsanitize=...)
out=$(mktemp -d); trap 'rm -rf "$out"' EXIT
# shellcheck disable=SC2086
gcc -std=c11 $flags -O2 -I"$src/core/include" "$src/scripts/bench/load_formats.c" $libs -o "$out/load_formats"
"$out/load_formats" "$out" "$n" "$reps"
