#!/usr/bin/env bash
# README.md's Lua examples run as written: every ```lua block is extracted and run by cdvr on
# the bundled data (share/data), each in a fresh temporary directory (its files land there).
# The per-frame fields the README names in backquotes (`read_ms` ... `frame_ms`, `variant`,
# `why`) in paragraphs about the player's rows must be fields of those rows.
cdvr=${1:?usage: test_readme.sh path/to/cdvr}
cdvr=$(cd "$(dirname "$cdvr")" && pwd)/$(basename "$cdvr")
src=${CDVR_SOURCE_DIR:-$(cd "$(dirname "$0")/.." && pwd)}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
passed=0; failed=0
check() { local name=$1; shift; if "$@"; then passed=$((passed+1)); else failed=$((failed+1)); echo "FAIL: $name" >&2; fi; }

awk -v dir="$tmp" '
  /^```lua[ \t]*$/ { n++; inblock = 1; file = sprintf("%s/block%d.lua", dir, n); next }
  /^```[ \t]*$/ && inblock { inblock = 0; close(file); next }
  inblock { print > file }
  END { print n > (dir "/count") }' "$src/README.md"
count=$(cat "$tmp/count")
check "README has Lua examples" [ "${count:-0}" -ge 1 ]

# (named in paragraphs about rows: other `*_ms` names are render statistics)
fields=$(awk 'BEGIN { RS = "" } /(^|[^a-z])[Rr]ows?([^a-z]|$)/' "$src/README.md" |
         grep -o '`[a-z_]*_ms`' | tr -d '`' | sort -u)
check "README names the stage fields" [ "$(echo "$fields" | wc -w)" -ge 7 ]
for i in $(seq 1 "${count:-0}"); do
  block="$tmp/block$i.lua"
  if grep -q 'p:run' "$block"; then # the player example: its rows carry the named fields
    for f in $fields variant why t; do
      echo "assert(report.frames[1].$f ~= nil, 'README names row field $f, rows lack it')" >>"$block"
    done
  fi
  mkdir -p "$tmp/run$i"
  (cd "$tmp/run$i" && "$cdvr" "$block" >"$tmp/out$i" 2>"$tmp/err$i")
  rc=$?
  check "README Lua block $i runs (rc $rc)" [ $rc -eq 0 ]
  [ $rc -eq 0 ] || { echo "--- block $i:" >&2; cat "$block" >&2; cat "$tmp/err$i" >&2; }
done
echo "$passed passed, $failed failed"
[ $failed -eq 0 ]
