#!/usr/bin/env bash
# Misuse scripts (tests/misuse/*.lua, issue 11): each runs as its own cdvr process under a time
# limit and must end as its first line says, "-- expect: error TEXT" (a Lua error, exit 1, TEXT
# in the message) or "-- expect: ok TEXT" (exit 0, TEXT printed); never by a signal, a sanitizer
# report or the time limit (the failure mode of a deadlock or an escaped runaway callback).
# The hostile files they load are made by test_hostile_files --make.
cdvr=${1:?usage: test_misuse.sh path/to/cdvr}
src=${CDVR_SOURCE_DIR:?CDVR_SOURCE_DIR not set}
bin=${CDVR_BINARY_DIR:-$(dirname "$cdvr")}
limit=${CDVR_MISUSE_TIMEOUT:-60}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
"$bin/test_hostile_files" --make "$tmp" || { echo "FAIL: cannot make the hostile files" >&2; exit 1; }
passed=0; failed=0
for script in "$src"/tests/misuse/*.lua; do
  expect=$(sed -n '1s/^-- expect: //p' "$script")
  [ -n "$expect" ] || continue              # common.lua
  name=$(basename "$script" .lua)
  kind=${expect%% *}; text=${expect#* }
  out=$(CDVR_MISUSE_DIR="$tmp" timeout -k 5 "$limit" "$cdvr" "$script" 2>&1); rc=$?
  why=""
  if [ $rc -eq 124 ] || [ $rc -eq 137 ]; then why="ran past ${limit} s (hang)"
  elif [ $rc -gt 128 ]; then why="killed by signal $((rc - 128))"
  elif grep -q "Sanitizer" <<<"$out"; then why="sanitizer report"
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
