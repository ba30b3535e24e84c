#!/usr/bin/env bash
# libfsm's one entry point for people and CI. On a fresh Debian 12 machine (as root, or with sudo)
# it installs whatever is missing, configures, builds and runs.
#
#   tools/dev.sh demo [ARGS...]   the main job: fsm-demo, the uterus session (ARGS go to it)
#   tools/dev.sh test             every test: GoogleTest suite, packaging, benchmark smoke runs,
#                                 then `sanitize` and `fuzz 60`
#   tools/dev.sh sanitize         the unit tests under ASan + UBSan, the threaded ones under TSan
#   tools/dev.sh fuzz [SECONDS]   each fuzzer for SECONDS (default 60) from its seeds, then the
#                                 regression inputs; a finding stops with the file to keep
#   tools/dev.sh bench [ARGS...]  the benchmarks, full length (ARGS go to Google Benchmark)
#   tools/dev.sh charts           measure (benchmarks + integrator accuracy) into docs/data and
#                                 draw docs/img/*.png; takes about 20 minutes
#   tools/dev.sh install-deps     only the install step
#
# Environment: FSM_BUILD_DIR (default build), FSM_BUILD_TYPE (default Release), FSM_JOBS.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
# ccache sees paths inside the checkout as relative ones, so a copy of the sources (the pip test's)
# that keeps the same layout reuses the objects compiled here.
export CCACHE_BASEDIR="$PWD"

# Every dependency is a Debian package (no network besides Debian's archive).
PACKAGES=(
  build-essential cmake ninja-build ccache pkg-config git
  libeigen3-dev libccd-dev libxsimd-dev
  libcgal-dev libgmp-dev libmpfr-dev libboost-dev nlohmann-json3-dev libcli11-dev libassimp-dev
  libgtest-dev libgmock-dev libbenchmark-dev libbullet-dev libsuitesparse-dev
  python3 python3-dev pybind11-dev python3-numpy python3-pytest
  python3-venv python3-pip python3-setuptools python3-wheel
  python3-matplotlib python3-distributed python3-meshio calculix-ccx
  libglfw3-dev libimgui-dev libegl-dev libgl-dev libosmesa6-dev libgl1-mesa-dri libstb-dev xvfb xauth
  clang libclang-rt-14-dev
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

# Configures (if needed) and builds TARGETS in DIR, compiling with CXXFLAGS only (the build type
# "Checked" adds none: -O1 -g1 below keeps the instrumented builds quick and their reports
# symbolised), with extra cmake arguments (words without spaces):
#   build_in DIR "CXXFLAGS" "CMAKE ARGS..." TARGET...
build_in() {
  local dir=$1 flags=$2 args=$3
  shift 3
  local launcher=()
  command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  # shellcheck disable=SC2086  # the extra arguments are words
  cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Checked -DFSM_BUILD_BENCHMARKS=OFF \
    -DFSM_BUILD_EXAMPLES=OFF -DFSM_BUILD_PYTHON=OFF -DFSM_BUILD_BUILDER=OFF \
    "-DCMAKE_CXX_FLAGS=$flags" "${launcher[@]}" $args >/dev/null
  cmake --build "$dir" -j "$JOBS" --target "$@"
}

# The runtime's unit tests under AddressSanitizer + UndefinedBehaviorSanitizer, and the tests that
# run threads (servo loop, devices, the Touch adapter, simulation) under ThreadSanitizer. Only what
# they test is built (the runtime, no CGAL), and the test programs run directly.
UNIT_TESTS=(test_voigt_link test_material test_sphere_model test_tetrahedral_mesh test_force_model
  test_stability test_integrators test_simulation test_skinning test_model_file test_shapes
  test_triangle_bvh test_volume_term test_contact test_haptic_device test_servo_loop
  test_malformed_models test_no_allocation test_continuum test_vtk_export test_worker_pool
  test_cutting test_grasper
  touch/test_touch_device)
THREAD_TESTS=(test_servo_loop test_haptic_device test_simulation test_worker_pool
  touch/test_touch_device)
# Skipped under the sanitizers (they run in the Release ctest above): the four resolution sweeps,
# which refine a block or a bar to fine spacing to check that a result converges. Their code paths
# are those of the smaller cases of the same suites, which do run instrumented; at -O1 under ASan
# they took 54-177 s each, 470 s of the 530 s of the ASan stage (measured 2026-11-28).
SANITIZER_SKIP="ContactSolver.BallForceConvergesAsTheSpacingShrinks"
SANITIZER_SKIP+=":ContactSolver.FaceContactHoldsUnderAFlatEndAtFineSpacing"
SANITIZER_SKIP+=":Continuum.SqueezedBlockCarriesEAStrainAtEveryResolution"
SANITIZER_SKIP+=":Simulation.GravityHangingBarReachesTheStaticElongation"
run_tests() {  # run_tests DIR PROGRAM...: each test program, stopping at the first failure
  local dir=$1 t
  shift
  for t in "$@"; do
    echo "tools/dev.sh: $dir: $t" >&2
    "$dir/tests/$t" --gtest_brief=1 "--gtest_filter=-$SANITIZER_SKIP" || return 1
  done
}
sanitize() {
  local dir=${BUILD_DIR}-asan
  # UBSan without the checks that tripled GCC's compile time on the Eigen-heavy files (119 s against
  # 44 s for force_model.cpp): a null or out-of-object access is reported by ASan itself, and the
  # fuzz build (clang) runs the file readers under clang's whole `undefined` group, alignment
  # included (alignment, pointer overflow and vptr then go unchecked in the rest of the runtime).
  local ub_off=null,pointer-overflow,alignment,object-size,vptr,nonnull-attribute
  ub_off+=,returns-nonnull-attribute
  build_in "$dir" "-O1 -g1 -fsanitize=address,undefined -fno-sanitize=$ub_off -fno-omit-frame-pointer -fno-sanitize-recover=undefined" \
    "" "${UNIT_TESTS[@]##*/}"
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1 \
    run_tests "$dir" "${UNIT_TESTS[@]}"
  dir=${BUILD_DIR}-tsan
  build_in "$dir" "-O1 -g1 -fsanitize=thread" "" "${THREAD_TESTS[@]##*/}"
  # setarch -R: GCC 12's TSan cannot map its shadow memory under the kernel's full ASLR.
  TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1 \
    setarch "$(uname -m)" -R bash -c "$(declare -p SANITIZER_SKIP); $(declare -f run_tests); run_tests \"\$@\"" _ \
    "$dir" "${THREAD_TESTS[@]}"
}

# libFuzzer (clang) on the model-file reader, the scene parser and the mesh parsers, each for
# SECONDS from a copy of its seeds (tests/fuzz/corpus), then the seeds and regression inputs.
fuzz() {
  local seconds=${1:-60} dir=${BUILD_DIR}-fuzz
  build_in "$dir" "-O1 -gline-tables-only -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined" \
    "-DCMAKE_CXX_COMPILER=clang++ -DFSM_BUILD_TESTS=OFF -DFSM_BUILD_FUZZERS=ON" \
    fuzz_model_file fuzz_scene fuzz_mesh
  local work=$dir/fuzz-work t
  rm -rf "$work"
  mkdir -p "$work/findings"
  # The scene fuzzer resolves mesh paths against its folder: give it the meshes its seeds name.
  cp data/uterus/*.obj tests/malformed/box.off "$work/"
  for t in cube.obj cube.off cube.stl cube.ply; do cp tests/malformed/box.off "$work/$t"; done
  for t in fuzz_model_file fuzz_scene fuzz_mesh; do
    cp -r "tests/fuzz/corpus/$t" "$work/corpus-$t"
    echo "tools/dev.sh: fuzzing $t for $seconds s" >&2
    if ! (cd "$work" && "$OLDPWD/$dir/tests/fuzz/$t" -max_total_time="$seconds" -timeout=10 \
          -rss_limit_mb=2048 -artifact_prefix=findings/ -print_final_stats=1 "corpus-$t" \
          >"$t.log" 2>&1); then
      tail -40 "$work/$t.log" >&2
      echo "tools/dev.sh: $t found an input that fails: $(ls "$work"/findings/*); fix it and keep" \
           "the file in tests/fuzz/regressions/$t/ (it then runs as a test)" >&2
      return 1
    fi
    grep -E "^stat::number_of_executed_units|^Done" "$work/$t.log" >&2 || true
  done
  ctest --test-dir "$dir" --output-on-failure -j "$JOBS" -L fuzz
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
    ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$JOBS"
    sanitize
    fuzz 60
    ;;
  sanitize)
    install_deps
    sanitize
    ;;
  fuzz)
    install_deps
    fuzz "$@"
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
