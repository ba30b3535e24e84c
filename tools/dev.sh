#!/usr/bin/env bash
# libfsm's one entry point for people and CI. On a fresh Debian 12 machine (as root, or with sudo)
# it installs whatever is missing, configures, builds and runs.
#
#   tools/dev.sh demo [ARGS...]   the main job: fsm-demo, the uterus session (ARGS go to it)
#   tools/dev.sh test             every test: GoogleTest suite, packaging, benchmark smoke runs
#   tools/dev.sh bench [ARGS...]  the benchmarks, full length (ARGS go to Google Benchmark)
#   tools/dev.sh charts           measure (benchmarks + integrator accuracy) into docs/data and
#                                 draw docs/img/*.png; takes about 20 minutes
#   tools/dev.sh install-deps     only the install step
#
# Environment: FSM_BUILD_DIR (default build), FSM_BUILD_TYPE (default Release), FSM_JOBS.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

# Every dependency is a Debian package (no network besides Debian's archive).
PACKAGES=(
  build-essential cmake ninja-build ccache pkg-config git
  libeigen3-dev libccd-dev
  libcgal-dev libgmp-dev libmpfr-dev libboost-dev nlohmann-json3-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  python3 python3-dev pybind11-dev python3-numpy python3-pytest
  python3-venv python3-pip python3-setuptools python3-wheel
  python3-matplotlib python3-distributed calculix-ccx
  libglfw3-dev libegl-dev libgl-dev libosmesa6-dev libgl1-mesa-dri libstb-dev xvfb xauth
)

install_deps() {
  local missing=() p
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0  # quiet when everything is present
  echo "tools/dev.sh: installing ${missing[*]}" >&2
  local sudo=()
  [ "$(id -u)" -ne 0 ] && sudo=(sudo)
  "${sudo[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo[@]}" apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null
}

BUILD_DIR=${FSM_BUILD_DIR:-build}
BUILD_TYPE=${FSM_BUILD_TYPE:-Release}
JOBS=${FSM_JOBS:-$(nproc)}

build() {
  local launcher=()
  command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  # Debian's Python (where python3-numpy lives), whatever python3 comes first on PATH.
  cmake -S . -B "$BUILD_DIR" -G Ninja -DCMAKE_BUILD_TYPE="$BUILD_TYPE" \
    -DPython_EXECUTABLE=/usr/bin/python3 "${launcher[@]}" >/dev/null
  # build [TARGET...]: only those targets (the demo needs just itself), else everything.
  local targets=()
  [ $# -gt 0 ] && targets=(--target "$@")
  cmake --build "$BUILD_DIR" -j "$JOBS" "${targets[@]}"
}

cmd=${1:-}
[ $# -gt 0 ] && shift
case "$cmd" in
  demo)
    install_deps
    build fsm-demo
    exec "$BUILD_DIR/examples/fsm-demo" "$@"
    ;;
  test)
    install_deps
    build
    exec ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$JOBS"
    ;;
  bench)
    install_deps
    build
    for b in "$BUILD_DIR"/bench/bench_*; do
      [ -x "$b" ] && "$b" "$@"
    done
    "$BUILD_DIR/bench/servo_latency" --seconds 30
    ;;
  charts)
    install_deps
    PACKAGES=(python3 python3-matplotlib)
    install_deps
    build
    mkdir -p docs/data
    for b in bench_force_model bench_integrators; do
      "$BUILD_DIR/bench/$b" --benchmark_out="docs/data/$b.json" --benchmark_out_format=json
    done
    "$BUILD_DIR/bench/integrator_accuracy" --out docs/data/integrator_accuracy.csv
    [ -x "$BUILD_DIR/bench/frame_accuracy" ] && "$BUILD_DIR/bench/frame_accuracy" --out docs/data/frame_accuracy.csv
    /usr/bin/python3 docs/charts.py
    ;;
  install-deps)
    install_deps
    ;;
  *)
    sed -n '2,12p' "$0" >&2
    exit 2
    ;;
esac
