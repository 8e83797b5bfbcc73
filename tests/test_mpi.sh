#!/usr/bin/env bash
# tests/test_mpi.sh CDVR - MPI ranks (DESIGN.md section 12), when cdvr is built with MPI:
#  - tests/lua/mpi_scene.lua under mpirun -np 1, 2 and 4 (oversubscribed on a small machine)
#    in both modes (distribute="time" and "bricks"): every frame matches the one-process
#    render (PSNR >= 50 dB) for a camera outside and one inside the volume, rows gathered on
#    rank 0, frames in one numbered sequence;
#  - a rank that cannot open its store, or raises in Lua during a run, ends every rank with a
#    non-zero status and its own message (MPI_Abort after the report), within a time limit;
#  - ranks that disagree on the distribute mode, the store, the camera or the frame count stop
#    with an error naming what differs, and a rank waiting at a barrier no other rank reaches
#    reports itself after CDVR_MPI_TIMEOUT seconds (tests/lua/mpi_agree.lua).
set -uo pipefail
cdvr=$1
src=${CDVR_SOURCE_DIR:-$(cd "$(dirname "$0")/.." && pwd)}
"$cdvr" -e 'os.exit(cdvr.mpi.built and 0 or 77)'
case $? in
  0) ;;
  77) echo "skip: cdvr built without MPI (-DCDVR_WITH_MPI=ON)"; exit 77 ;;
  *) echo "FAIL: cdvr does not start"; exit 1 ;;
esac
mpirun=${CDVR_MPIEXEC:-mpirun}
flags=(--oversubscribe)
[ "$(id -u)" -eq 0 ] && flags+=(--allow-run-as-root)
export OMPI_MCA_btl_vader_single_copy_mechanism=none # shared memory without ptrace (containers)
# Sanitizer builds: OpenMPI's MCA components leak at MPI_Finalize and are unloaded by then (their
# frames cannot be named for a suppression), so leak checking is off in processes under mpirun;
# address and UB checks stay on. cdvr's own code is leak-checked by the other tests.
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

devices=(cpu)
if [ "${CDVR_MPI_TEST_CL:-1}" = 1 ] && "$cdvr" -e 'os.exit(cdvr.cl_info() and 0 or 1)' 2>/dev/null; then
  devices+=(cl)
fi
for device in "${devices[@]}"; do
  for mode in time bricks; do
    for n in 1 2 4; do
      d="$tmp/$mode-$n-$device"
      mkdir -p "$d"
      timeout 300 "$mpirun" "${flags[@]}" -np "$n" "$cdvr" "$src/tests/lua/mpi_scene.lua" \
        "$mode" "$d" "$device" || fail "$mode, $n ranks, $device"
    done
  done
done

# Failures: rank 1 stops, rank 0 waits in a collective call; both must end.
for what in "open" "raise time" "raise bricks"; do
  set -- $what
  out="$tmp/fail-$1-${2:-}.txt"
  timeout 120 "$mpirun" "${flags[@]}" -np 2 "$cdvr" "$src/tests/lua/mpi_fail.lua" "$1" "$tmp" \
    ${2:-} >"$out" 2>&1
  rc=$?
  [ "$rc" -ne 124 ] || { cat "$out"; fail "$what: still running after 120 s (a rank hangs)"; }
  [ "$rc" -ne 0 ] || { cat "$out"; fail "$what: exit status 0"; }
  grep -q "rank 1 of 2" "$out" || { cat "$out"; fail "$what: no message naming rank 1"; }
  case $1 in
    open) grep -q "no_such_store.cdv" "$out" || { cat "$out"; fail "open: the message names no file"; } ;;
    raise) grep -q "camera broke on purpose" "$out" || { cat "$out"; fail "raise: no Lua message"; } ;;
  esac
  if grep -q "should have stopped" "$out"; then cat "$out"; fail "$what: rank 0 went on"; fi
  echo "failure '$what': exit $rc with rank 1's message"
done
# Disagreement and waits no other rank ends (CDVR_MPI_TIMEOUT=3): every rank ends, non-zero,
# within the time limit, with a message naming what differs, or naming the waiting rank.
for what in mode store camera path frames barrier; do
  out="$tmp/agree-$what.txt"
  start=$(date +%s)
  CDVR_MPI_TIMEOUT=3 timeout 120 "$mpirun" "${flags[@]}" -x CDVR_MPI_TIMEOUT -np 2 "$cdvr" \
    "$src/tests/lua/mpi_agree.lua" "$what" "$tmp" >"$out" 2>&1
  rc=$?
  took=$(( $(date +%s) - start ))
  [ "$rc" -ne 124 ] || { cat "$out"; fail "$what: still running after 120 s (a rank hangs)"; }
  [ "$rc" -ne 0 ] || { cat "$out"; fail "$what: exit status 0"; }
  if grep -q "should have stopped" "$out"; then cat "$out"; fail "$what: a rank went on"; fi
  case $what in
    mode) want="the distribute mode (rank 0: time, rank 1: bricks)" ;;
    store) want="the store (rank" ;;
    camera) want="the camera (rank" ;;
    path) want="frame 3: the ranks disagree on its camera" ;;
    frames) want="the frame count (rank 0: 4, rank 1: 5)" ;;
    barrier) want="rank 1 of 2: cdvr.mpi.barrier(): the other ranks did not come within 3 s" ;;
  esac
  grep -qF "$want" "$out" || { cat "$out"; fail "$what: no message with '$want'"; }
  [ "$what" = barrier ] || [ "$what" = path ] || grep -qF "distribute: the ranks disagree" "$out" || { cat "$out"; fail "$what: no disagreement message"; }
  echo "disagreement '$what': exit $rc after $took s: $(grep -oF "$want" "$out" | head -1)"
done

echo "test_mpi: ok"
