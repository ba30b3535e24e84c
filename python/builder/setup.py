"""Builds the fsm-builder distribution (GPL-3.0-or-later): the fsm_builder package and its CGAL
extension _fsm_build, from the same CMake project as the runtime.

    .venv/bin/pip install --no-build-isolation .               # the runtime, fsm (BSD-3-Clause)
    .venv/bin/pip install --no-build-isolation python/builder  # this, fsm-builder (GPL)

Works offline with Debian 12's packages (as the runtime, plus libcgal-dev, libgmp-dev,
libmpfr-dev, nlohmann-json3-dev). The version comes from the top-level CMakeLists.txt.
"""
import sys
from pathlib import Path

from setuptools import setup

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from cmake_extension import CMakeBuild, CMakeExtension, version  # noqa: E402

setup(
    version=version(),
    packages=["fsm_builder"],
    ext_modules=[CMakeExtension("fsm_builder._fsm_build", "_fsm_build", "FSM_PYTHON_BUILDER_DIR",
                                builder=True)],
    cmdclass={"build_ext": CMakeBuild},
    zip_safe=False,
)
