#!/usr/bin/env bash
# scripts/setup.sh - the README's set-up: install Debian packages, build, then run.
#   scripts/setup.sh demo           install, build, run scripts/demo.lua on the bundled data
#   scripts/setup.sh test           install, build, run the whole test suite (ctest)
#   scripts/setup.sh test-sanitize  the same with AddressSanitizer + UBSan (build-asan/)
# Environment: CDVR_JOBS (parallel build jobs, default: number of cores).
set -euo pipefail
cd "$(dirname "$0")/.."

mode=${1:-demo}
packages=(build-essential cmake pkg-config liblua5.4-dev libteem-dev libniftiio-dev libznz-dev
          libnifti2-dev zlib1g-dev libzfp-dev libbz2-dev
          liblzo2-dev libexpat1-dev liblz4-dev libzstd-dev libtiff-dev libhdf5-dev libnetcdf-dev opencl-headers ocl-icd-opencl-dev pocl-opencl-icd clinfo libstb-dev
          libreadline-dev gnuplot-nox
          libavformat-dev libavcodec-dev libswscale-dev libavutil-dev # movies (core/movie)
          libglfw3-dev libegl-dev libgl-dev libopengl-dev libegl-mesa0 libgl1-mesa-dri
          xvfb xauth libxtst6 python3
          python3-vtk9 # tests/test_vtk_reader.sh: VTK's readers as the reference
          libgdcm-dev libgdcm-tools # plugins/dicom (C++ on GDCM; gdcmdump to inspect files)
          libopenmpi-dev openmpi-bin paraview-dev paraview) # MPI ranks + IceT (CDVR_WITH_MPI)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}" >&2
  sudo=""; [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
fi

jobs=${CDVR_JOBS:-$(nproc)}
build() { # build DIR [cmake args...]
  local dir=$1; shift
  cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@" >/dev/null
  cmake --build "$dir" -j"$jobs"
}

case "$mode" in
  demo)
    build build
    ./build/cdvr scripts/demo.lua ;;
  test)
    build build -DCDVR_WITH_MPI=ON
    # PoCL is installed above: an OpenCL test that cannot open its device fails, not skips
    export CDVR_REQUIRE_OPENCL=1
    cd build && ctest --output-on-failure -j"$jobs" ;;
  test-sanitize)
    build build-asan -DCDVR_SANITIZE=ON -DCDVR_WITH_MPI=ON
    export CDVR_REQUIRE_OPENCL=1
    # intercept_tls_get_addr=0: GCC 12's sanitizer runtime takes a dynamic TLS block (PoCL's
    # and LLVM's) that malloc happened to place 16 bytes into a page for a pre-2.25 glibc
    # header, and LeakSanitizer's tracer then dies at exit ("Tracer caught signal 11") after a
    # test passed: 2 of about 60 runs of test_cl_decode beside other tests
    cd build-asan && ASAN_OPTIONS=detect_leaks=1:intercept_tls_get_addr=0 \
      UBSAN_OPTIONS=print_stacktrace=1 LSAN_OPTIONS=suppressions=$PWD/../tests/lsan.supp \
      ctest --output-on-failure -j"$jobs" ;;
  *)
    echo "usage: scripts/setup.sh demo|test|test-sanitize" >&2; exit 2 ;;
esac
