#!/usr/bin/env bash
# Budget escapes and data files (tests/escape/*.lua, issue 21 items 2 and 3): each script runs as
# its own cdvr process under a time limit and a memory limit and must end as its first line says,
# "-- expect: error TEXT" (exit 1, TEXT in the output) or "-- expect: ok TEXT" (exit 0, TEXT
# printed). A hang (the time limit), an out-of-memory kill, a signal or a sanitizer report is a
# failure, never a stuck suite. The scripts write their hostile TF, camera and path files into a
# scratch directory (CDVR_ESCAPE_DIR).
# Memory: prlimit --as (address space, 3 GiB); under AddressSanitizer, which reserves terabytes
# of address space, ASan's own hard_rss_limit_mb instead.
cdvr=${1:?usage: test_escape.sh path/to/cdvr}
src=${CDVR_SOURCE_DIR:?CDVR_SOURCE_DIR not set}
limit=${CDVR_ESCAPE_TIMEOUT:-60}
mem_mb=${CDVR_ESCAPE_MEMORY_MB:-3072}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
if ldd "$cdvr" 2>/dev/null | grep -q libasan; then
  run_limited() { ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}hard_rss_limit_mb=$mem_mb" "$@"; }
else
  run_limited() { prlimit --as=$((mem_mb * 1048576)) "$@"; }
fi
passed=0; failed=0
for script in "$src"/tests/escape/*.lua; do
  expect=$(sed -n '1s/^-- expect: //p' "$script")
  [ -n "$expect" ] || continue              # common.lua
  name=$(basename "$script" .lua)
  kind=${expect%% *}; text=${expect#* }
  rm -rf "$tmp"/*
  out=$(CDVR_ESCAPE_DIR="$tmp" run_limited timeout -k 5 "$limit" "$cdvr" "$script" 2>&1); rc=$?
  why=""
  if [ $rc -eq 124 ] || [ $rc -eq 137 ]; then why="ran past ${limit} s (hang)"
  elif [ $rc -gt 128 ]; then why="killed by signal $((rc - 128))"
  elif grep -q "Sanitizer\|runtime error:" <<<"$out"; then why="sanitizer report"
  elif grep -q "not enough memory\|cannot allocate" <<<"$out" && ! grep -qF -- "$text" <<<"$out"; then
    why="ran out of memory (limit ${mem_mb} MB)"
  elif [ "$kind" = error ] && [ $rc -ne 1 ]; then why="exit $rc, expected a Lua error (exit 1)"
  elif [ "$kind" = ok ] && [ $rc -ne 0 ]; then why="exit $rc, expected success"
  elif ! grep -qF -- "$text" <<<"$out"; then why="output lacks \"$text\""
  fi
  if [ -z "$why" ]; then
    passed=$((passed + 1))
  else
    failed=$((failed + 1))
    printf 'FAIL: %s: %s\n%s\n' "$name" "$why" "$(tail -n 12 <<<"$out")" >&2
  fi
done
echo "$passed passed, $failed failed"
[ $failed -eq 0 ] && [ $passed -gt 0 ]
