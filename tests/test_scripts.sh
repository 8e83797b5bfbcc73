#!/usr/bin/env bash
# The user-facing scripts run end to end: report.lua on a small series (CSV header and rows,
# PNG chart), regress.lua against share/regress/reference.lua, demo.lua (short: its stills, JPEG
# and frames are written, the bundled CT loads in HU).
cdvr=${1:?usage: test_scripts.sh path/to/cdvr}
src=${CDVR_SOURCE_DIR:-$(cd "$(dirname "$0")/.." && pwd)}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
passed=0; failed=0
check() { local name=$1; shift; if "$@"; then passed=$((passed+1)); else failed=$((failed+1)); echo "FAIL: $name" >&2; fi; }

cd "$src" || exit 1
"$cdvr" scripts/report.lua share/data/mpld_asl_64x64x24x25_f32.nii.gz --timesteps 6 --frames 6 \
  --width 48 --out "$tmp/report" >"$tmp/report.out" 2>"$tmp/report.err"
check "report.lua exit 0" [ $? -eq 0 ]
check "report.csv header" [ "$(head -1 "$tmp/report/report.csv")" = "dataset,config,codec,bpv,ratio,fps,frame_ms,image_psnr,volume_psnr,maxerr,stage2,unpack_mb_s" ]
check "report.csv rows (raw + 8 PVTC variants + 4 zfp rates)" [ "$(tail -n +2 "$tmp/report/report.csv" | wc -l)" -eq 13 ]
check "report.csv zfp2 row" grep -q '^mpld_asl_64x64x24x25_f32,zfp2,zfp,2.0000,0.2500,' "$tmp/report/report.csv"
check "report.csv raw is lossless" grep -q '^mpld_asl_64x64x24x25_f32,raw,raw,8.0000,1.0000,.*,inf,inf,0.0000,none,[0-9.]*$' "$tmp/report/report.csv"
check "report.csv S4T3 ratio 5/48" grep -q '^mpld_asl_64x64x24x25_f32,S4T3,pvtc,0.8333,0.1042,' "$tmp/report/report.csv"
check "report.png is a PNG" [ "$(head -c 8 "$tmp/report/report.png" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ]

# several datasets: one chart, a colour and legend entry each; a printf pattern from --first;
# a dataset that fails is reported and the others are still written (exit status 1)
cp share/data/neghip_66x66x66_u8.nrrd "$tmp/ng_07.nrrd"; cp share/data/neghip_66x66x66_u8.nrrd "$tmp/ng_08.nrrd"
"$cdvr" scripts/report.lua share/data/mpld_asl_64x64x24x25_f32.nii.gz "$tmp/ng_%02d.nrrd" "$tmp/missing_%d.nrrd" \
  --first 7 --timesteps 3 --frames 3 --width 32 --zfp none --out "$tmp/multi" >"$tmp/multi.out" 2>"$tmp/multi.err"
check "report.lua with a failing dataset exits 1" [ $? -eq 1 ]
check "the failure is reported" grep -q "dataset $tmp/missing_%d.nrrd failed: .*missing_7.nrrd" "$tmp/multi.err"
check "failed.txt names it" grep -q "missing_7.nrrd" "$tmp/multi/failed.txt"
check "rows of both good datasets" [ "$(grep -c '^mpld_asl_64x64x24x25_f32,' "$tmp/multi/report.csv")" -eq 9 ] && \
  [ "$(grep -c '^ng,' "$tmp/multi/report.csv")" -eq 9 ]
check "the pattern started at --first (2 timesteps)" grep -q '^ng,raw,raw,8.0000,1.0000,' "$tmp/multi/report.csv"
# --stage2 auto: each variant's stage-2 choice (chunks per codec) and its unpack speed
"$cdvr" scripts/report.lua share/data/neghip_66x66x66_u8.nrrd --frames 2 --width 16 --zfp none \
  --stage2 auto --out "$tmp/auto" >"$tmp/auto.out" 2>"$tmp/auto.err"
check "report.lua --stage2 auto exit 0" [ $? -eq 0 ]
check "--stage2 auto: the choice per variant" grep -q '^neghip_66x66x66_u8,raw,raw,.*,auto:[a-z0-9=/]*,[0-9.]*$' "$tmp/auto/report.csv"
check "one legend entry per dataset" [ "$(grep -c 'with points.* title "' "$tmp/multi/report.gp")" -eq 2 ]
check "a colour per dataset" [ "$(grep -o 'lc rgb "#[0-9a-f]*"' "$tmp/multi/report.gp" | sort -u | wc -l)" -eq 2 ]
check "multi-dataset report.png is a PNG" [ "$(head -c 8 "$tmp/multi/report.png" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ]

"$cdvr" scripts/regress.lua >"$tmp/regress.out" 2>"$tmp/regress.err"
rc=$?
check "regress.lua passes" [ $rc -eq 0 ]
[ $rc -eq 0 ] || cat "$tmp/regress.err" >&2
# a moved figure must fail and be named
sed 's/value = \([0-9.]*\)/value = \1 + 5/' share/regress/reference.lua > "$tmp/moved.lua"
"$cdvr" scripts/regress.lua --reference "$tmp/moved.lua" >/dev/null 2>"$tmp/moved.err"
check "regress.lua fails on moved figures" [ $? -ne 0 ]
check "regress.lua names the moved check" grep -q "MOVED ml/S1T3/volume_psnr" "$tmp/moved.err"

"$cdvr" scripts/demo.lua --frames 6 --size 256 --out "$tmp/demo" >"$tmp/demo.out" 2>&1
check "demo.lua exit 0" [ $? -eq 0 ]
check "demo frames written" [ -s "$tmp/demo/0006.png" ]
for f in head_ct head_ct_flat head_ct_mip asl_t02; do
  check "demo $f.png is a PNG" [ "$(head -c 8 "$tmp/demo/$f.png" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ]
done
check "demo head_ct.jpg is a JPEG" [ "$(head -c 3 "$tmp/demo/head_ct.jpg" | od -An -tx1 | tr -d ' \n')" = "ffd8ff" ]
check "demo CT in HU" grep -q '^data: headsq_64x64x93_i16.nrrd  64x64x93 i16, -1024 .. 2902 HU$' "$tmp/demo.out"
check "demo table printed" grep -q '^S1T3 ' "$tmp/demo.out"

echo "$passed passed, $failed failed"
[ $failed -eq 0 ]
