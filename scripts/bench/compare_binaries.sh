#!/usr/bin/env bash
# scripts/bench/compare_binaries.sh OLD_CDVR NEW_CDVR [ROUNDS] [SCRIPT [ARGS...]]
# Runs a benchmark script (default scripts/bench/decode_speed.lua) with two cdvr binaries in
# alternation (old, new, old, new, ...: both see the same machine load), ROUNDS times each
# (default 5), and prints for every row key (the first two CSV columns) and every numeric
# column the median of each binary and the ratio new/old. The machine is shared and noisy:
# only the ratios measured in one such run mean much.
set -euo pipefail
old=$1 new=$2 rounds=${3:-5}
shift $(( $# < 3 ? $# : 3 ))
script=${1:-scripts/bench/decode_speed.lua}
[ $# -gt 0 ] && shift
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for ((r = 1; r <= rounds; r++)); do
  for which in old new; do
    bin=$old; [ $which = new ] && bin=$new
    [ -t 2 ] && printf '\rround %d/%d: %s ' "$r" "$rounds" "$which" >&2
    "$bin" "$script" "$@" > "$work/$which.$r.csv"
  done
done
[ -t 2 ] && printf '\n' >&2
lua_prog='
local rounds, dir = tonumber(arg[1]), arg[2]
local function read(which)
  local cols, rows, order = nil, {}, {}
  for r = 1, rounds do
    local f = assert(io.open(("%s/%s.%d.csv"):format(dir, which, r)))
    local header = f:read("l")
    cols = {}
    for c in header:gmatch("[^,]+") do cols[#cols + 1] = c end
    for line in f:lines() do
      local v = {}
      for c in (line .. ","):gmatch("([^,]*),") do v[#v + 1] = c end
      local key = v[1] .. "," .. v[2]
      if not rows[key] then rows[key] = {}; order[#order + 1] = key end
      for i = 3, #cols do
        rows[key][i] = rows[key][i] or {}
        table.insert(rows[key][i], tonumber(v[i]))
      end
    end
    f:close()
  end
  return cols, rows, order
end
local function median(t)
  table.sort(t)
  local n = #t
  if n == 0 then return 0 / 0 end
  return n % 2 == 1 and t[(n + 1) // 2] or (t[n // 2] + t[n // 2 + 1]) / 2
end
local cols, old, order = read("old")
local _, new = read("new")
local out = {cols[1], cols[2]}
for i = 3, #cols do
  out[#out + 1] = cols[i] .. "_old"; out[#out + 1] = cols[i] .. "_new"; out[#out + 1] = cols[i] .. "_ratio"
end
print(table.concat(out, ","))
for _, key in ipairs(order) do
  local row = {key}
  for i = 3, #cols do
    local a, b = median(old[key][i] or {}), median((new[key] or {})[i] or {})
    row[#row + 1] = ("%.1f,%.1f,%s"):format(a, b, a > 0 and ("%.3f"):format(b / a) or "")
  end
  print(table.concat(row, ","))
end'
printf '%s\n' "$lua_prog" > "$work/aggregate.lua"
"$new" "$work/aggregate.lua" "$rounds" "$work"
