#!/bin/sh
# Regenerates the validation: reference FEM curves (CalculiX), the simulated experiment,
# calibration, metrics and the charts docs/img/validation_*.png (docs/validation.md).
#
#   validation/run.sh [--no-reference]      # from the repository root
#
# --no-reference keeps the stored CalculiX curves (validation/reference/*.csv; regenerating them
# takes about an hour of ccx on two cores) and reruns everything else.
set -eu
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${FSM_VALIDATION_BUILD:-$ROOT/build-val}
PY=/usr/bin/python3

cmake -S "$ROOT" -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DFSM_BUILD_PYTHON=OFF \
  -DFSM_BUILD_BENCHMARKS=OFF -DFSM_BUILD_EXAMPLES=OFF >/dev/null
ninja -C "$BUILD" fsm-indent fsm-stability-map

if [ "${1:-}" != "--no-reference" ]; then
  "$PY" "$ROOT/validation/make_reference.py"
fi
rm -rf "$BUILD/validation-work"
"$PY" "$ROOT/validation/validate.py" --indent "$BUILD/validation/fsm-indent" \
  --stability "$BUILD/validation/fsm-stability-map"
