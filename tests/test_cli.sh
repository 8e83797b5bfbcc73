#!/usr/bin/env bash
# The cdvr executable: exit statuses, -e, script arguments, errors with file:line and a
# traceback, --help/--version, the console (piped), require "cdvr", cdvr.help().
cdvr=${1:?usage: test_cli.sh path/to/cdvr}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
passed=0; failed=0
check() { # name, condition command...
  local name=$1; shift
  if "$@"; then passed=$((passed+1)); else failed=$((failed+1)); echo "FAIL: $name" >&2; fi
}
run() { out=$("$cdvr" "$@" 2>"$tmp/err"); rc=$?; err=$(cat "$tmp/err"); }

run --version;            check "version rc" [ $rc -eq 0 ]; check "version text" grep -q '^cdvr [0-9]' <<<"$out"
run --help;               check "help rc" [ $rc -eq 0 ]; check "help text" grep -q 'usage: cdvr' <<<"$out"
run --bogus;              check "bad option rc 2" [ $rc -eq 2 ]; check "bad option message" grep -q "unrecognized option '--bogus'" <<<"$err"
run -e;                   check "-e without code rc 2" [ $rc -eq 2 ]
run </dev/null;           check "no script, no tty rc 2" [ $rc -eq 2 ]
run -e 'print(cdvr.version == require("cdvr").version)'
check "-e and require" [ "$out" = "true" ]
run -e 'cdvr.help()';     check "help lists functions" grep -q '^cdvr.load' <<<"$out"
check "help lists player" grep -q '^cdvr.player' <<<"$out"

printf 'print(#arg, arg[0] ~= nil, ...)\n' > "$tmp/args.lua"
run "$tmp/args.lua" one two
check "script args" [ "$out" = "$(printf '2\ttrue\tone\ttwo')" ]

printf 'local x = 1\nlocal function f()\n  error("boom")\nend\nf()\n' > "$tmp/bad.lua"
run "$tmp/bad.lua"
check "runtime error rc 1" [ $rc -eq 1 ]
check "error file:line" grep -q "bad.lua:3: boom" <<<"$err"
check "traceback" grep -q "stack traceback" <<<"$err"
printf 'local x = = 1\n' > "$tmp/syntax.lua"
run "$tmp/syntax.lua";    check "syntax error rc 1" [ $rc -eq 1 ]; check "syntax message" grep -q "syntax.lua:1:" <<<"$err"
run "$tmp/missing.lua";   check "missing script rc 1" [ $rc -eq 1 ]; check "missing script message" grep -q "missing.lua" <<<"$err"
run -e 'cdvr.load("x.raw", {dims="bad"})'; check "misuse raises rc 1" [ $rc -eq 1 ]
run -e 'cdvr.load("/nonexistent.nrrd")'
check "a missing file is an error naming it" [ $rc -eq 1 ]; check "missing file message" grep -q "/nonexistent.nrrd: cannot open: No such file" <<<"$err"

# console: expressions print like the lua REPL, statements run, multi-line input continues,
# errors are reported and the console goes on
out=$(printf '1 + 2\nx = 40\nx + 2\nfor i = 1, 2 do\n  print("i", i)\nend\nerror("oops")\nprint("after")\n' | "$cdvr" -i 2>"$tmp/err"); rc=$?
check "console rc" [ $rc -eq 0 ]
check "console expression" grep -qx '3' <<<"$out"
check "console global" grep -qx '42' <<<"$out"
check "console multi-line" grep -q "i	2" <<<"$out"
check "console error reported" grep -q "oops" "$tmp/err"
check "console continues" grep -qx 'after' <<<"$out"
out=$(printf 'cdvr.tf("grayscale")\n' | "$cdvr" -i 2>/dev/null)
check "console prints userdata" grep -q 'cdvr.TF' <<<"$out"

echo "$passed passed, $failed failed"
[ $failed -eq 0 ]
