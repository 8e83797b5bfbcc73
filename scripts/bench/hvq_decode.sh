#!/bin/bash
# scripts/bench/hvq_decode.sh - decode speed per thread of hvq stores, an old cdvr binary
# against a new one, alternating (old, new, old, new, ...): the old binary decodes its hvq store,
# the new one its hvq, hvqc and hvqc shared=1 stores of the same volume (st:decode of the whole
# frame; the hvq decoders run on one thread). Prints, per binary and variant, the median
# GB/s of decoded voxels over ROUNDS rounds (each round: the median of 3 decodes).
#
#   scripts/bench/hvq_decode.sh OLD_CDVR NEW_CDVR VOLUME [ROUNDS=5] [BRICKS=1]
set -euo pipefail
old=$1 new=$2 vol=$3 rounds=${4:-5} bricks=${5:-1}
out=${CDVR_BENCH_OUT:-/tmp/cdvr-hvq}/decode
mkdir -p "$out"
encode() { # binary store spec
  "$1" -e "local v = assert(cdvr.load('$vol'))
    assert(cdvr.encode(v, {variants = {$3}, path = '$2', progress = false,
                           bricks = {$bricks, $bricks, $bricks}}))"
}
timing() { # binary store -> 'variant gbps' lines
  "$1" -e "local st = assert(cdvr.open('$2'))
    local X, Y, Z = table.unpack(st:info().dims)
    for _, v in ipairs(st:info().variants) do
      local t = {}
      for r = 1, 3 do local t0 = cdvr.clock(); st:decode(1, v.name); t[r] = cdvr.clock() - t0 end
      table.sort(t)
      print(v.name, X * Y * Z / t[2] / 1e9)
    end"
}
encode "$old" "$out/old.cdv" "{codec = 'hvq'}"
encode "$new" "$out/new.cdv" "{codec = 'hvq'}, {codec = 'hvqc'}, {codec = 'hvqc', shared = 1}"
: > "$out/times.txt"
for r in $(seq "$rounds"); do
  timing "$old" "$out/old.cdv" | sed 's/^/old /' >> "$out/times.txt"
  timing "$new" "$out/new.cdv" | sed 's/^/new /' >> "$out/times.txt"
done
echo "binary,variant,decode_gbps_median,rounds,loadavg"
sort "$out/times.txt" | awk -v la="$(cut -d' ' -f1-3 /proc/loadavg)" '
  { k = $1 "," $2; v[k, ++n[k]] = $3 }
  END { for (k in n) { m = n[k]; for (i = 1; i <= m; i++) a[i] = v[k, i];
          for (i = 1; i <= m; i++) for (j = i + 1; j <= m; j++) if (a[j] < a[i]) { t = a[i]; a[i] = a[j]; a[j] = t }
          printf "%s,%.4f,%d,%s\n", k, (m % 2 ? a[(m + 1) / 2] : (a[m / 2] + a[m / 2 + 1]) / 2), m, la } }' | sort
