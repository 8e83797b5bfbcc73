#!/usr/bin/env bash
# The window (DESIGN.md section 11) under a virtual X display (xvfb-run): the scene checks of
# tests/lua/window_checks.lua and tests/lua/window_scene_checks.lua (what the window shares
# with the player: policy stats, callback budgets, default variant and device; keys r, q,
# Esc; re-framing), tests/lua/test_messages.lua with a window open (its misuse messages), a console session through a pseudo-terminal that opens a window,
# changes the TF (the change shows in the next frame) and quits with status 0; without a display
# `cdvr -i` prints one notice and stays a console, and cdvr.window raises a clear error.
# Skips (77) when xvfb-run or python3 is missing; in a build without GL it checks the errors.
cdvr=${1:?usage: test_window.sh path/to/cdvr}
src=${CDVR_SOURCE_DIR:-$(cd "$(dirname "$0")/.." && pwd)}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
passed=0; failed=0
check() { # name, condition command...
  local name=$1; shift
  if "$@"; then passed=$((passed+1)); else failed=$((failed+1)); echo "FAIL: $name" >&2; fi
}

# no display: one notice, a working console; cdvr.window says why it cannot open
out=$(printf 'print(1 + 1)\n' | env -u DISPLAY -u WAYLAND_DISPLAY "$cdvr" -i 2>"$tmp/err"); rc=$?
check "console without display rc" [ $rc -eq 0 ]
check "console without display works" grep -qx '2' <<<"$out"
check "one notice line" [ "$(grep -c 'console only' "$tmp/err")" -eq 1 ]
env -u DISPLAY -u WAYLAND_DISPLAY "$cdvr" -e 'cdvr.window{}' 2>"$tmp/err"; rc=$?
check "cdvr.window without display fails" [ $rc -ne 0 ]
check "cdvr.window names the reason" grep -Eq 'no display|without GL' "$tmp/err"

have_gl=$("$cdvr" -e 'io.write(tostring(cdvr.have_gl))')
if [ "$have_gl" != true ]; then
  echo "$passed passed, $failed failed (no GL in this build)"
  [ $failed -eq 0 ]; exit
fi
if ! command -v xvfb-run >/dev/null || ! command -v python3 >/dev/null; then
  echo "skipped: xvfb-run or python3 missing ($passed passed, $failed failed)"
  [ $failed -eq 0 ] && exit 77 || exit 1
fi

# screenshots without a path (w:screenshot(), key p) land in the working directory: the
# temporary one, not the build tree
cdvr=$(cd "$(dirname "$cdvr")" && pwd)/$(basename "$cdvr")
cd "$tmp" || exit 1
xvfb-run -a "$cdvr" "$src/tests/lua/window_checks.lua"; rc=$?
check "window scene checks" [ $rc -eq 0 ]
# the scene contract shared with the player; under a timeout: a callback that loops must end
# with the budget error, never hang the window
timeout 300 xvfb-run -a "$cdvr" "$src/tests/lua/window_scene_checks.lua"; rc=$?
check "window scene contract checks (rc $rc)" [ $rc -eq 0 ]
# misuse messages of cdvr.window and the w: methods (the rest of tests/lua/test_messages.lua too)
timeout 300 xvfb-run -a "$cdvr" "$src/tests/lua/test_messages.lua" >/dev/null; rc=$?
check "messages with a window (rc $rc)" [ $rc -eq 0 ]

# the console beside a window: a TF typed in the console shows in the next frame
xvfb-run -a python3 "$src/tests/pty_session.py" --timeout 120 -- \
  env CDVR_HISTORY="$tmp/history" "$cdvr" -i ::: \
  'expect:window open as `window`' 'expect:> ' \
  'send:v = cdvr.generate("ml", {dims = {40, 40, 40}})' \
  'send:window:set{volume = v, tf = "hot", overlay = false}' \
  'send:a = window:read()' \
  'send:window:set{tf = "grayscale"}' \
  'send:b = window:read()' \
  'send:print("changed", cdvr.compare(a, b).psnr < 30)' 'expect:changed\strue' \
  'send:print("same", cdvr.compare(b, cdvr.render(v, {tf = "grayscale", camera = window:camera()})).psnr >= 50)' \
  'expect:same\strue' \
  'send:os.exit(0)' 'exit:0'
check "console session with a window exits 0" [ $? -eq 0 ]
check "history kept" grep -q 'window:set{tf = "grayscale"}' "$tmp/history"

echo "$passed passed, $failed failed"
[ $failed -eq 0 ]
