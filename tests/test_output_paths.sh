#!/usr/bin/env bash
# Output paths (issue 11 item 6), through the real cdvr executable:
#  - v:save_raw, img:save, cdvr.encode and player captures write through symbolic links (the
#    link stays, its target gets the data);
#  - a target that is not a regular file (FIFO, directory, a device node when run as root) is
#    refused with a clear message and left as it was;
#  - a full file system (a 64 KiB tmpfs, where a mount is allowed: root or `unshare -rm`) gives
#    an error naming the target, and leaves neither a partial file nor a temporary one;
#  - every catchable terminating signal (INT TERM QUIT HUP USR1 USR2 PIPE ALRM XCPU XFSZ VTALRM
#    PROF) sent to a real cdvr process during an encode or a capture removes its temporary file;
#    the process still ends by that signal (exit 128 + n); SIGKILL leaves nothing under any name
#    with O_TMPFILE, and without it (CDVR_ATOMIC_NAMED=1) the next writer removes the stale file.
cdvr=${1:?usage: test_output_paths.sh path/to/cdvr}
cdvr=$(cd "$(dirname "$cdvr")" && pwd)/$(basename "$cdvr")
tmp=$(mktemp -d); trap 'umount "$tmp/full" 2>/dev/null; rm -rf "$tmp"' EXIT
passed=0; failed=0
check() { # name, condition command...
  local name=$1; shift
  if "$@"; then passed=$((passed+1)); else failed=$((failed+1)); echo "FAIL: $name" >&2; fi
}
run() { out=$(cd "$tmp" && timeout -k 5 60 "$cdvr" -e "$1" 2>&1); rc=$?; }
no_temporaries() { ! ls "$1" 2>/dev/null | grep -q '\.tmp'; }

# Lua helpers: a small volume, a frame, and a call that prints the error whichever way it comes
# (nil, message or a raised error).
prelude='
local v = cdvr.generate("sphere", {dims = {16, 16, 16}, timesteps = 3})
local function frame() return cdvr.render(v, {tf = cdvr.tf("hot"), camera = cdvr.orbit_camera(v, {width = 16, height = 16})}) end
local function try(f, ...)
  local ok, a, b = pcall(f, ...)
  if ok and a then print("OK") else print("ERR " .. tostring(ok and b or a)) end
end
local function encode(path) return cdvr.encode(v, {path = path, progress = false}) end
local function capture(pattern)
  local st = assert(cdvr.open("s.cdv"))
  local p = cdvr.player{store = st, tf = cdvr.tf("hot"), width = 16, height = 16, device = "cpu", out = pattern}
  p:run{frames = 1}
  return true
end
'
run "$prelude assert(encode('s.cdv'))"; check "encode a store" [ $rc -eq 0 ]

# ---- symbolic links are written through ---------------------------------------------------------
mkdir -p "$tmp/real" "$tmp/frames"
for name in raw png cdv; do echo old > "$tmp/real/target.$name"; ln -s "real/target.$name" "$tmp/link.$name"; done
ln -s ../real/frame.png "$tmp/frames/1.png"
run "$prelude try(v.save_raw, v, 'link.raw'); try(frame().save, frame(), 'link.png'); try(encode, 'link.cdv')
     try(capture, 'frames/%d.png'); try(cdvr.open, 'link.cdv')"
check "writes through links succeed ($out)" [ "$(grep -c '^OK' <<<"$out")" -eq 5 ]
for name in raw png cdv; do
  check "link.$name stays a link" [ -L "$tmp/link.$name" ]
  check "target.$name got the data" [ "$(wc -c <"$tmp/real/target.$name")" -gt 4 ]
done
check "capture frame link stays" [ -L "$tmp/frames/1.png" ]
check "capture wrote the link's target" [ -s "$tmp/real/frame.png" ]
check "raw through link = 3 x 16^3 bytes" [ "$(wc -c <"$tmp/real/target.raw")" -eq 12288 ]
check "no temporaries beside the targets" no_temporaries "$tmp/real"

# ---- non-regular targets are refused and left alone ---------------------------------------------
mkfifo "$tmp/fifo.raw" "$tmp/fifo.png" "$tmp/fifo.cdv" "$tmp/frames/2.png"
mkdir "$tmp/dir.raw"
run "$prelude try(v.save_raw, v, 'fifo.raw'); try(frame().save, frame(), 'fifo.png'); try(encode, 'fifo.cdv')
     try(v.save_raw, v, 'dir.raw')
     try(function() local st = assert(cdvr.open('s.cdv'))
       cdvr.player{store = st, tf = cdvr.tf('hot'), width = 16, height = 16, device = 'cpu', out = 'frames/%d.png'}:run{frames = 2} end)"
check "no hang or crash on FIFO targets (rc $rc)" [ $rc -eq 0 ]
check "FIFO targets refused ($out)" [ "$(grep -c '^ERR .*not a regular file (a FIFO)' <<<"$out")" -eq 4 ]
check "capture names the frame" grep -q "^ERR .*frames/2.png: not a regular file (a FIFO)" <<<"$out"
check "directory target refused" grep -q "^ERR .*dir.raw: not a regular file (a directory)" <<<"$out"
for f in fifo.raw fifo.png fifo.cdv frames/2.png; do check "$f is still a FIFO" [ -p "$tmp/$f" ]; done
check "no temporaries after refusals" no_temporaries "$tmp"
if [ "$(id -u)" -eq 0 ] && mknod "$tmp/null.raw" c 1 3 2>/dev/null; then
  # as root the rename used to replace a device with a plain file; a private node, never /dev/null
  run "$prelude try(v.save_raw, v, 'null.raw'); try(encode, 'null.raw')"
  check "device target refused ($out)" [ "$(grep -c '^ERR .*not a regular file (a character device)' <<<"$out")" -eq 2 ]
  check "device node still a device" [ -c "$tmp/null.raw" ]
else
  echo "note: device-node case skipped (needs root)"
fi

# ---- a full file system -------------------------------------------------------------------------
mkdir "$tmp/full"
mounted=""
if mount -t tmpfs -o size=64k tmpfs "$tmp/full" 2>/dev/null; then mounted=direct
elif unshare -rm true 2>/dev/null; then mounted=namespace
fi
full_lua="$prelude
local big = cdvr.generate('ml', {dims = {48, 48, 48}, timesteps = 2})
try(big.save_raw, big, 'full/big.raw')
try(function() return cdvr.encode(big, {path = 'full/big.cdv', codec = 'raw', stage2 = 'none', progress = false}) end)"
case $mounted in
  direct) run "$full_lua" ;;
  namespace) out=$(cd "$tmp" && unshare -rm sh -c 'mount -t tmpfs -o size=64k tmpfs full && exec "$0" -e "$1"' \
                   "$cdvr" "$full_lua" 2>&1); rc=$? ;;
esac
if [ -n "$mounted" ]; then
  check "ENOSPC reported for save_raw, naming the target ($out)" grep -q "^ERR full/big.raw: cannot write: No space left on device" <<<"$out"
  # cdvr.encode raises (lcdvr.h): the message has the caller's position and the function first
  check "ENOSPC reported for encode, naming the target ($out)" grep -q "^ERR .*cdvr.encode: full/big.cdv: write failed: No space left on device" <<<"$out"
  check "nothing left on the full file system" [ -z "$(ls -A "$tmp/full")" ]
else
  echo "note: ENOSPC case skipped (no tmpfs mount allowed here)"
fi

# ---- signals during an encode and a capture --------------------------------------------------
# Background jobs start with SIGINT and SIGQUIT ignored; `env --default-signal` gives the child
# the default disposition of every signal, as a terminal's foreground job has. mode "named"
# (CDVR_ATOMIC_NAMED=1) takes the path of a filesystem without O_TMPFILE: a visible
# out.cdv.tmp.PID.XXXXXX; mode "unnamed" is the O_TMPFILE file, seen only as the process's
# descriptor /proc/PID/fd/N -> "DIR/#INODE (deleted)".
temp_seen() { # mode, pid
  if [ "$1" = named ]; then ls "$tmp/sig" 2>/dev/null | grep -q '\.tmp\.'
  else ls -l "/proc/$2/fd" 2>/dev/null | grep -q "$tmp/sig/#"; fi
}
signal_run() { # signal, expected exit, what (encode|capture), mode (named|unnamed)
  local sig=$1 want=$2 what=$3 mode=$4 code named=0
  [ "$mode" = named ] && named=1
  rm -rf "$tmp/sig"; mkdir "$tmp/sig"
  if [ "$what" = encode ]; then
    code='local v = cdvr.generate("ml", {dims = {64, 64, 64}, timesteps = 24})
          cdvr.encode(v, {path = "sig/out.cdv", progress = false})'
  else # frames whose PNG takes longer than their render (the camera looks away from the box);
    # loop: the store has 3 timesteps, which alone end the run within about 0.3 s, before a
    # loaded machine's poll below may see a temporary file
    code='local st = assert(cdvr.open("s.cdv"))
          local p = cdvr.player{store = st, tf = cdvr.tf("hot"), width = 700, height = 700, device = "cpu", loop = true,
                                out = "sig/%03d.png", camera = cdvr.camera{eye = {100, 0, 0}, center = {200, 0, 0}, up = {0, 0, 1}}}
          p:run{frames = 400}'
  fi
  (cd "$tmp" && CDVR_ATOMIC_NAMED=$named exec env --default-signal "$cdvr" -e "$code") &
  local pid=$! seen=""
  for _ in $(seq 3000); do  # up to about 30 s for the temporary file to appear
    if temp_seen "$mode" $pid; then seen=1; break; fi
    kill -0 $pid 2>/dev/null || break
    sleep 0.01
  done
  kill -s "$sig" $pid 2>/dev/null
  wait $pid; local rc=$?
  local left; left=$(ls -A "$tmp/sig" | tr '\n' ' ')
  check "$what ($mode): a temporary file was seen before SIG$sig" [ -n "$seen" ]
  check "$what ($mode): ended by SIG$sig (exit $rc, want $want)" [ $rc -eq "$want" ]
  [ "$what" = encode ] && check "$what ($mode): SIG$sig: nothing under the final name" [ ! -e "$tmp/sig/out.cdv" ]
  if [ "$sig" != KILL ]; then
    check "$what ($mode): SIG$sig left no temporary file ($left)" no_temporaries "$tmp/sig"
  elif [ "$mode" = unnamed ]; then
    check "$what ($mode): SIGKILL left nothing under any name ($left)" [ -z "$left" ]
  else # the stale file carries the dead writer's pid; the next writer of out.cdv removes it
    check "$what ($mode): SIGKILL left out.cdv.tmp.$pid.* ($left)" grep -q "^out\.cdv\.tmp\.$pid\.[^ ]* $" <<<"$left"
    (cd "$tmp" && CDVR_ATOMIC_NAMED=1 "$cdvr" -e 'cdvr.encode(cdvr.generate("sphere", {dims = {8, 8, 8}}), {path = "sig/out.cdv", progress = false})')
    left=$(ls -A "$tmp/sig" | tr '\n' ' ')
    check "$what ($mode): the next writer removed the stale temporary ($left)" [ "$left" = "out.cdv " ]
  fi
}
if env --default-signal=INT true 2>/dev/null; then
  for sig in INT TERM QUIT HUP USR1 USR2 PIPE ALRM XCPU XFSZ VTALRM PROF; do
    n=$(kill -l "$sig")
    want=$((128 + n))
    signal_run "$sig" "$want" encode named
  done
  signal_run TERM 143 encode unnamed
  signal_run KILL 137 encode unnamed
  signal_run KILL 137 encode named
  signal_run INT 130 capture named
  signal_run TERM 143 capture named
  signal_run TERM 143 capture unnamed
else
  echo "note: signal cases skipped (env --default-signal missing)"
fi

echo "$passed passed, $failed failed"
[ $failed -eq 0 ]
