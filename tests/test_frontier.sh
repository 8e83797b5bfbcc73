#!/usr/bin/env bash
# scripts/frontier.lua end to end on two tiny datasets (--quick, no generated series): exit 0,
# the CSV's columns, one row per variant and dataset, raw lossless at 8 bpv, auto's choices
# named, the pareto column equal to the front recomputed from the rows written (per dataset),
# a PNG chart; a missing dataset is reported and fails the run while the others are still
# written.
cdvr=${1:?usage: test_frontier.sh path/to/cdvr}
src=${CDVR_SOURCE_DIR:-$(cd "$(dirname "$0")/.." && pwd)}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
passed=0; failed=0
check() { local name=$1; shift; if "$@"; then passed=$((passed+1)); else failed=$((failed+1)); echo "FAIL: $name" >&2; fi; }

cd "$src" || exit 1
"$cdvr" scripts/frontier.lua share/data/neghip_66x66x66_u8.nrrd share/data/mpld_asl_64x64x24x25_f32.nii.gz \
  --quick --series none --timesteps 2 --frames 2 --width 16 --zfp none --out "$tmp/f" >"$tmp/f.out" 2>"$tmp/f.err"
check "frontier.lua exit 0" [ $? -eq 0 ]
[ -s "$tmp/f/frontier.csv" ] || cat "$tmp/f.err" >&2
csv="$tmp/f/frontier.csv"
check "frontier.csv columns" [ "$(head -1 "$csv")" = "dataset,config,codec,stage2,bpv,image_psnr,volume_psnr,decode_gb_s,unpack_gb_s,fps,frame_ms,pareto" ]
nvar=$("$cdvr" -e 'local n = 8 for _, c in ipairs(cdvr.codecs()) do if c.name == "hvq" or c.name == "hvqc" then n = n + 1 end end print(n)')
check "one row per variant and dataset ($nvar each)" [ "$(grep -c '^neghip_66x66x66_u8,' "$csv")" -eq $nvar ] && \
  [ "$(grep -c '^mpld_asl_64x64x24x25_f32,' "$csv")" -eq $nvar ]
check "every row has 12 fields" [ "$(awk -F, 'NR > 1 && NF != 12' "$csv" | wc -l)" -eq 0 ]
check "raw is lossless at 8 bpv" grep -q '^neghip_66x66x66_u8,raw,raw,none,8.0000,inf,inf,' "$csv"
check "stage 2 recorded" grep -q '^neghip_66x66x66_u8,S4T3_zstd,pvtc,zstd,' "$csv"
check "auto lists what its chunks took" grep -Eq '^neghip_66x66x66_u8,raw_auto,raw,auto:(none|lzo|lz4|zstd)=[0-9]' "$csv"
# the front, recomputed: a row is on it unless another row of its dataset has bpv <= and
# image_psnr >= (inf the highest), one of them strictly
front=$(awk -F, 'NR > 1 { n++; d[n] = $1; b[n] = $5 + 0; p[n] = ($6 == "inf") ? 1e30 : $6 + 0; m[n] = $12 }
  END { bad = 0; on = 0
        for (i = 1; i <= n; i++) { dom = 0
          for (j = 1; j <= n; j++) if (j != i && d[j] == d[i] && b[j] <= b[i] && p[j] >= p[i] && (b[j] < b[i] || p[j] > p[i])) dom = 1
          if ((dom ? 0 : 1) != m[i]) bad++; on += m[i] }
        print bad, on }' "$csv")
check "pareto column is the front of the rows ($front: wrong, on front)" [ "${front%% *}" = 0 ] && [ "${front##* }" -ge 2 ]
check "lossless raw_zstd beats raw on the front" grep -q '^neghip_66x66x66_u8,raw,raw,.*,0$' "$csv"
check "frontier.png is a PNG" [ "$(head -c 8 "$tmp/f/frontier.png" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ]
check "a front line per dataset" [ "$(grep -c 'title ".* front"' "$tmp/f/frontier.gp")" -eq 2 ]

"$cdvr" scripts/frontier.lua share/data/neghip_66x66x66_u8.nrrd "$tmp/missing.nrrd" --quick --series none \
  --frames 1 --width 16 --zfp none --out "$tmp/g" >"$tmp/g.out" 2>"$tmp/g.err"
check "a failing dataset exits 1" [ $? -eq 1 ]
check "failed.txt names it" grep -q "missing.nrrd" "$tmp/g/failed.txt"
check "the other dataset is written" [ "$(grep -c '^neghip_66x66x66_u8,' "$tmp/g/frontier.csv")" -eq $nvar ]

echo "test_frontier: $passed passed, $failed failed"
[ $failed -eq 0 ]
