#!/usr/bin/env bash
# Player captures to movies (issue 24 items 1-2), through the real cdvr executable:
#  - one run captures the same frames to PNG, mkv/FFV1 and mp4/H.264 (96x80, 10 frames): the
#    FFV1 frames are the PNGs exactly, the H.264 ones >= 35 dB (build/test_movie compare reads
#    them back with libavformat/libavcodec); frame count and rate as asked (fps= 12, default:
#    target_fps or 25); two captures of the same run give byte-identical mkv and mp4 files;
#  - cdvr.movie{} from a script's own loop with `local m <close>`: committed at the scope's end,
#    dropped when the scope ends by an error;
#  - a capture killed meanwhile (SIGKILL, or SIGTERM with a named temporary file) leaves no file
#    under the final name, and SIGTERM no temporary either;
#  - an unwritable path and an unknown container are clear errors at cdvr.player{};
#  - progress (frames of total, fps, ETA) on stderr when it is a terminal, nothing otherwise;
#  - scripts/movie.lua turns the bundled 4D NIfTI into a movie with the frames and rate asked.
# Skipped (77) in a build without FFmpeg (cdvr.has_movie false).
cdvr=${1:?usage: test_movie.sh path/to/cdvr}
cdvr=$(cd "$(dirname "$cdvr")" && pwd)/$(basename "$cdvr")
bin=${CDVR_BINARY_DIR:-$(dirname "$cdvr")}
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
passed=0; failed=0
check() { # name, condition command...
  local name=$1; shift
  if "$@"; then passed=$((passed+1)); else failed=$((failed+1)); echo "FAIL: $name" >&2; fi
}
cd "$tmp" || exit 1
[ "$("$cdvr" -e 'print(cdvr.has_movie)')" = true ] || { echo "test_movie: built without FFmpeg: skipped"; exit 77; }

cat > scene.lua <<'LUA'
local vol = cdvr.generate("sphere", {dims = {32, 32, 32}, timesteps = 10})
st = assert(cdvr.encode(vol, {variants = {{codec = "raw"}}, path = "s.cdv", progress = false}))
tf = cdvr.tf("hot")
cam = function(frame) return cdvr.orbit_camera(vol, {width = 96, height = 80, azimuth = 9 * frame}) end
function capture(out, extra)
  local o = {store = st, tf = tf, camera = cam, out = out, device = "cpu"}
  for k, v in pairs(extra or {}) do o[k] = v end
  local p = cdvr.player(o)
  p:run{frames = 10}
  p:close()
end
LUA
cat > run.lua <<'LUA'
dofile("scene.lua")
capture("png/%04d.png")
capture("a.mkv", {fps = 12})
capture("b.mkv", {fps = 12})
capture("a.mp4")
capture("b.mp4")
capture("c.mp4", {target_fps = 8, pace = false})
LUA
"$cdvr" run.lua > run.log 2>&1; rc=$?
check "captures run (rc $rc: $(tail -3 run.log))" [ $rc -eq 0 ]
check "FFV1 capture = the PNGs exactly, 10 frames at 12 fps" "$bin/test_movie" compare a.mkv png/%04d.png 10 exact 12
check "H.264 capture >= 35 dB of the PNGs, 10 frames at 25 fps" "$bin/test_movie" compare a.mp4 png/%04d.png 10 35 25
check "fps default: target_fps (8)" "$bin/test_movie" compare c.mp4 png/%04d.png 10 35 8
check "two FFV1 captures: identical files" cmp -s a.mkv b.mkv
check "two H.264 captures: identical files" cmp -s a.mp4 b.mp4

# cdvr.movie from a script's loop: <close> commits; an error in the scope drops the file
cat > loop.lua <<'LUA'
dofile("scene.lua")
local vol = cdvr.generate("sphere", {dims = {16, 16, 16}})
do
  local m <close> = cdvr.movie{path = "loop.gif", fps = 5}
  for i = 1, 4 do
    local img = cdvr.render(vol, {tf = tf, camera = cdvr.orbit_camera(vol, {width = 40, height = 30, azimuth = 20 * i})})
    assert(img:save(("loop%d.png"):format(i)))
    m:add(img)
  end
  assert(tostring(m):match("loop.gif %(gif, 4 frames%)"), tostring(m))
end
local ok, e = pcall(function()
  local m <close> = cdvr.movie{path = "dropped.mp4"}
  m:add(cdvr.render(vol, {tf = tf, camera = cdvr.orbit_camera(vol, {width = 40, height = 30})}))
  error("stop here")
end)
assert(not ok and tostring(e):match("stop here"))
print(pcall(cdvr.player, {store = st, tf = tf, out = "/nonexistent-dir/m.mp4"}))
print(pcall(cdvr.player, {store = st, tf = tf, out = "m.avi"}))
print(pcall(cdvr.player, {store = st, tf = tf, out = "m%03d.mp4"}))
print(pcall(cdvr.player, {store = st, tf = tf, out = "m.mkv", crf = 20}))
print(pcall(cdvr.player, {store = st, tf = tf, out = "m%03d.png", fps = 20}))
print(pcall(cdvr.movie, {path = "m.avi"}))
LUA
"$cdvr" loop.lua > loop.log 2>&1; rc=$?
check "loop script (rc $rc: $(tail -3 loop.log))" [ $rc -eq 0 ]
check "<close> committed loop.gif: 4 frames at 5 fps, >= 24 dB of the PNGs" "$bin/test_movie" compare loop.gif loop%d.png 4 24 5
check "an error in the scope drops the movie" [ ! -e dropped.mp4 ]
check "unwritable path: clear error" grep -q "false.*/nonexistent-dir/m.mp4: cannot create temporary file: No such file" loop.log
check "unknown container in out=: clear error" grep -q "false.*option 'out' = \"m.avi\".*or a movie file (.mp4, .webm, .mkv, .gif)" loop.log
check "frame number in a movie name: refused" grep -q "false.*\"m%03d.mp4\": a movie file" loop.log
check "crf for FFV1: refused" grep -q "false.*m.mkv: crf applies to h264 and vp9, not to ffv1" loop.log
check "fps= without a movie: refused" grep -q "false.*option 'fps' applies to a movie out=" loop.log
check "cdvr.movie unknown container" grep -q "false.*m.avi: unknown movie container '.avi'" loop.log
ls | grep -q '\.tmp\.' && check "no temporary files left" false

# scripts/movie.lua: a 4D file to a movie in one line
src=${CDVR_SOURCE_DIR:-$(cd "$(dirname "$0")/.." && pwd)}
"$cdvr" "$src/scripts/movie.lua" "$src/share/data/mpld_asl_64x64x24x25_f32.nii.gz" asl.mkv --frames 6 \
  --width 64 --height 48 --fps 10 --annotate > script.log 2>&1; rc=$?
check "scripts/movie.lua (rc $rc: $(tail -3 script.log))" [ $rc -eq 0 ]
check "scripts/movie.lua: 6 frames at 10 fps" "$bin/test_movie" compare asl.mkv - 6 0 10
"$cdvr" "$src/scripts/movie.lua" x.nii asl.mkv --frame 6 > script.log 2>&1
check "scripts/movie.lua: unknown option named" grep -q "unknown option --frame" script.log

# progress on a terminal (script(1) gives the capture a pseudo-terminal), none otherwise
cat > prog.lua <<'LUA'
dofile("scene.lua")
capture("prog.mp4")
LUA
if command -v script >/dev/null; then
  script -qc "'$cdvr' prog.lua" /dev/null > pty.log 2>&1
  check "progress on a terminal: $(tr '\r' '\n' < pty.log | tail -2 | head -1)" grep -q "capture prog.mp4: 10/10 frames, .* fps, ETA 0 s" pty.log
fi
"$cdvr" prog.lua 2> nopty.log
check "no progress when stderr is not a terminal" [ ! -s nopty.log ]

# a killed capture: frame= says when frames are being written
cat > kill.lua <<'LUA'
dofile("scene.lua")
local p = cdvr.player{store = st, tf = tf, camera = cam, out = "killed.mp4", device = "cpu", loop = true,
                      frame = function(row) if row.frame == 3 then io.stderr:write("writing\n") end end}
p:run{frames = 100000}
LUA
for sig in KILL TERM; do
  rm -f killed.mp4 killed.mp4.tmp.* kill.log
  if [ $sig = TERM ]; then export CDVR_ATOMIC_NAMED=1; fi
  "$cdvr" kill.lua 2> kill.log & pid=$!
  for _ in $(seq 1 300); do grep -q writing kill.log 2>/dev/null && break; sleep 0.1; done
  named=$(ls killed.mp4.tmp.* 2>/dev/null | wc -l)
  kill -$sig $pid; wait $pid; rc=$?
  check "SIGKILL/TERM capture was writing ($sig: $(head -c 300 kill.log))" grep -q writing kill.log
  check "$sig: no file under the final name" [ ! -e killed.mp4 ]
  if [ $sig = TERM ]; then
    check "TERM: the named temporary existed while writing ($named)" [ "$named" -eq 1 ]
    check "TERM: the temporary is removed (rc $rc)" [ -z "$(ls killed.mp4.tmp.* 2>/dev/null)" ]
    unset CDVR_ATOMIC_NAMED
  fi
done

echo "test_movie.sh: $passed passed, $failed failed"
[ $failed -eq 0 ]
