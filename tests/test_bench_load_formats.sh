#!/usr/bin/env bash
# scripts/bench/load_formats.sh still builds and runs (a 16^3 volume, one round): every format
# is saved, loaded back voxel for voxel (the bench checks that itself) and timed, and the table
# has a row per format. Timings are not checked.
cdvr=${1:?usage: test_bench_load_formats.sh path/to/cdvr}
build=$(cd "$(dirname "$cdvr")" && pwd)
src=${CDVR_SOURCE_DIR:-$(cd "$(dirname "$0")/.." && pwd)}
command -v gcc >/dev/null || { echo "skip: no gcc"; exit 77; }
out=$(bash "$src/scripts/bench/load_formats.sh" "$build" 16 1 2>&1) || { echo "FAIL: $out"; exit 1; }
rows=$(echo "$out" | grep -cE '^(NRRD|NIfTI|VTI|MHA|TIFF) ')
[ "$rows" -eq 10 ] || { echo "FAIL: $rows format rows in"; echo "$out"; exit 1; }
echo "$out" | grep -q '^load average' || { echo "FAIL: no load average line"; exit 1; }
echo "1 passed, 0 failed"
