#!/usr/bin/env bash
# scripts/bench/hostile_cli.sh CDVR: issue 21 items 5, 8 and 9 at the Lua level (unbounded steps
# and rates, messages, a policy name with a zero byte), one line per case, 20 s limit each; run
# with an old and a new binary to compare.
cdvr=${1:?usage: hostile_cli.sh CDVR}
out_file=$(mktemp); trap 'rm -f "$out_file"' EXIT
run() { # name, lua code
  timeout 20 "$cdvr" -e "$2" > "$out_file" 2>&1; rc=$?
  out=$(head -1 "$out_file" | cut -c1-140)
  [ $rc -eq 124 ] && out="ran past 20 s"
  [ $rc -gt 128 ] && out="killed by signal $((rc - 128))"
  printf '%-22s %s\n' "$1" "$out"
}
V='local v = cdvr.generate("sphere", {dims = {32, 32, 32}}) local tf = cdvr.tf("hot") local cam = cdvr.orbit_camera(v, {width = 64, height = 64})'
run step_1e-6 "$V cdvr.render(v, {tf = tf, camera = cam, step = 1e-6, device = 'cpu'}) print('rendered')"
run step_inf "$V cdvr.render(v, {tf = tf, camera = cam, step = math.huge, device = 'cpu'}) print('rendered')"
run plugin_load_nil "cdvr.plugin.load(nil)"
run error_tostring "error(setmetatable({}, {__tostring = function() return 'my error object' end}))"
run open_missing "print(cdvr.open('/nonexistent.cdv'))"
run read_mbps_tiny "$V local st = cdvr.encode(v, {path = os.tmpname(), variants = {{codec = 'raw'}}, progress = false}) local p = cdvr.player{store = st, tf = tf, width = 16, height = 16, read_mbps = 1e-300, device = 'cpu'} p:run{frames = 1} print('played')"
run policy_nul "$V local st = cdvr.encode(v, {path = os.tmpname(), variants = {{codec = 'raw'}, {codec = 'pvtc', S = 4, T = 3}}, progress = false}) local p = cdvr.player{store = st, tf = tf, width = 16, height = 16, device = 'cpu', policy = function() return 'S4T3\0junk' end} p:run{frames = 1} print('played')"
