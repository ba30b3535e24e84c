#!/usr/bin/env bash
# `pip install .` offline into a fresh venv over Debian's Python, then import and step.
#   pip_install.sh SOURCE_DIR WORK_DIR
set -euo pipefail
src=$1
work=$2
rm -rf "$work"
mkdir -p "$work"
/usr/bin/python3 -m venv --system-site-packages "$work/venv"
# A copy of the sources, so setuptools' scratch files never land in the checkout.
mkdir -p "$work/src"
tar -C "$src" --exclude="./build*" --exclude=./.git --exclude=./.venv -cf - . | tar -C "$work/src" -xf -
# One CMake tree for both distributions, where the checkout keeps its own (build/): with
# CCACHE_BASEDIR at the checkout (tools/dev.sh sets it), the compiler's arguments then read the same
# as in the checkout's build and ccache reuses its objects instead of compiling everything again.
export FSM_CMAKE_BUILD_DIR="$work/src/build"
"$work/venv/bin/pip" install --no-build-isolation --no-index --quiet "$work/src"
cd "$work"  # not where a build tree's fsm/ could shadow the installed one
# The runtime wheel is BSD and holds no GPL code: no builder extension, and fsm.build says where
# the builder is.
"$work/venv/bin/python" - <<'PY'
import glob, os, fsm
here = os.path.dirname(fsm.__file__)
assert not glob.glob(os.path.join(here, "*fsm_build*")), os.listdir(here)
try:
    import fsm.build  # noqa: F401
    raise SystemExit("fsm.build imported without the fsm-builder distribution")
except ImportError as e:
    assert "fsm-builder" in str(e), e
PY
"$work/venv/bin/pip" show fsm > "$work/fsm.meta"
grep -q "^License: BSD-3-Clause" "$work/fsm.meta"
# The builder (GPL) as its own distribution.
"$work/venv/bin/pip" install --no-build-isolation --no-index --quiet "$work/src/python/builder"
"$work/venv/bin/pip" show fsm-builder > "$work/fsm-builder.meta"
grep -q "^License: GPL-3.0-or-later" "$work/fsm-builder.meta"
cd "$work"
FSM_SRC="$work/src" "$work/venv/bin/python" - <<'PY'
import fsm, fsm.build, numpy as np
assert fsm.__file__.startswith(__import__("sys").prefix), fsm.__file__
m = fsm.SphereModel()
r = m.add_region("b", fsm.Material(density=1050, youngs_modulus=13150, viscosity=10.26))
fsm.add_tetrahedral_part(m, fsm.make_cube_lattice((0, 0, 0), (3, 3, 3), 0.005), r, 0.0025)
sim = fsm.Simulation(m)
assert sim.step(1e-3).advanced
import os
model, report, table = fsm.build.build_model(os.path.join(os.environ["FSM_SRC"], "data/uterus/uterus.json"))
assert report["spheres"] > 500, report["spheres"]
print("pip-installed fsm", fsm.__version__, "from", fsm.__file__, "steps fine; builds the uterus:",
      report["spheres"], "spheres")
PY
