#!/usr/bin/env bash
# The console through a pseudo-terminal (tests/pty_session.py), as at a terminal: Ctrl-C
# interrupts a Lua loop, a long render and a playback with "interrupted!" and the session goes
# on; Ctrl-C at the prompt clears the line; the history file holds each line as soon as it is
# entered and the session's last line after os.exit(). Skips (77) without python3.
cdvr=${1:?usage: test_console.sh path/to/cdvr}
src=${CDVR_SOURCE_DIR:-$(cd "$(dirname "$0")/.." && pwd)}
command -v python3 >/dev/null || { echo "skipped: python3 missing"; exit 77; }
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
passed=0; failed=0
check() { # name, condition command...
  local name=$1; shift
  if "$@"; then passed=$((passed+1)); else failed=$((failed+1)); echo "FAIL: $name" >&2; fi
}
session() { # steps... : one console session without a display
  env -u DISPLAY -u WAYLAND_DISPLAY python3 "$src/tests/pty_session.py" --timeout 120 -- \
    env CDVR_HISTORY="$tmp/history" "$cdvr" -i ::: "$@"
}
history=yes
ldd "$cdvr" 2>/dev/null | grep -q libreadline || history=no
in_history=()
[ $history = yes ] && in_history=("file:$tmp/history:for i = 1, 1e15 do end")

# a plain Lua loop; the line is in the history file while it still runs
session 'expect:> ' \
  'send:print("loop" .. "ing"); for i = 1, 1e15 do end' 'expect:looping' 'sleep:0.3' \
  "${in_history[@]}" \
  intr 'expect:interrupted!' 'sleep:0.5' \
  'send:print("alive" .. 1)' 'expect:alive1' \
  'type:x = ' 'sleep:0.3' intr 'sleep:0.5' 'send:print("prompt" .. 2)' 'expect:prompt2' \
  'send:os.exit(3)' 'exit:3'
check "Ctrl-C in a loop and at the prompt, os.exit status" [ $? -eq 0 ]
if [ $history = yes ]; then
  check "history: os.exit line saved" grep -qx 'os.exit(3)' "$tmp/history"
  check "history: every line" [ "$(grep -c . "$tmp/history")" -ge 3 ]
fi

# a long render (one thread, a 3000x3000 image at step 0.05: minutes if not interrupted)
session 'expect:> ' \
  'send:v = cdvr.generate("ml", {dims = {64, 64, 64}}); print("made" .. 1)' 'expect:made1' \
  'send:print("render" .. "ing"); img = cdvr.render(v, {tf = "hot", camera = cdvr.orbit_camera(v, {width = 3000, height = 3000}), step = 0.05, threads = 1})' \
  'expect:rendering' 'sleep:0.5' intr 'expect:interrupted!' 'sleep:0.5' \
  'send:print("image", img)' 'expect:image\snil' \
  'send:print("small", (cdvr.render(v, {tf = "hot", camera = cdvr.orbit_camera(v, {width = 8, height = 8})})))' \
  'expect:small\scdvr.Image' \
  'send:os.exit()' 'exit:0'
check "Ctrl-C in a long render" [ $? -eq 0 ]

# playback of a store. Every line waits for its output, which its echo does not hold (a
# line typed ahead while the encode ran once let "playing" match the echo, and the Ctrl-C
# meant for the playback interrupted cdvr.player under load)
session 'expect:> ' \
  'send:st = cdvr.encode(cdvr.generate("sphere", {dims = {40, 40, 40}, timesteps = 4}), {codec = "raw", path = "'"$tmp"'/s.cdv"}); print("encoded" .. 1)' \
  'expect:encoded1' \
  'send:p = cdvr.player{store = st, loop = true, tf = cdvr.tf("hot"), camera = cdvr.orbit_camera({dims = {40, 40, 40}}, {width = 128, height = 128})}; print("made" .. 2)' \
  'expect:made2' \
  'send:print("play" .. "ing"); r = p:run{frames = 1000000}' 'expect:playing' 'sleep:0.5' \
  intr 'expect:interrupted!' 'sleep:0.5' \
  'send:print("report", r)' 'expect:report\snil' \
  'send:print("again", #p:run{frames = 2}.frames)' 'expect:again\s2' \
  'send:os.exit()' 'exit:0'
check "Ctrl-C in a playback" [ $? -eq 0 ]

echo "$passed passed, $failed failed"
[ $failed -eq 0 ]
