#!/usr/bin/env bash
# scripts/bench/hostile_loaders.sh CDVR DIR: loads every hostile file of hostile_loaders.py (written
# first into DIR) with CDVR; one line per file:
# "loaded ..." (what the volume became), "refused: MESSAGE", or the signal / time limit.
# Run with an old and a new binary to compare (issue 21 items 4-5: every case but the negative
# spacing, which is an axis running backwards, must be refused).
cdvr=${1:?usage: hostile_loaders.sh CDVR DIR} dir=${2:?usage: hostile_loaders.sh CDVR DIR}
/usr/bin/python3 "$(dirname "$0")/hostile_loaders.py" "$dir" || exit 1
out_file=$(mktemp); trap 'rm -f "$out_file"' EXIT
for f in "$dir"/*.ni* "$dir"/*.nrrd "$dir"/a/b/*.nhdr; do
  timeout 20 "$cdvr" -e "
    local ok, v = pcall(cdvr.load, '$f')
    if not ok then print('refused: ' .. tostring(v):gsub('\n', ' '):sub(1, 110)) return end
    local lo, hi = v:range()
    print(('loaded %s spacing %s dir %s range %s..%s'):format(table.concat({v:dims()}, 'x'), table.concat({v:spacing()}, ','), table.concat({v:direction()}, ','), tostring(lo), tostring(hi)))" > "$out_file" 2>&1
  rc=$?
  out=$(tail -1 "$out_file")
  [ $rc -eq 124 ] && out="ran past 20 s"
  [ $rc -gt 128 ] && out="killed by signal $((rc - 128))"
  printf '%-18s %s\n' "$(basename "$f")" "$out"
done
