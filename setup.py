"""Builds the fsm Python package (BSD-3-Clause): setuptools drives CMake, which compiles the _fsm
extension (the runtime only; the GPL builder is the separate fsm-builder distribution in
python/builder, which `import fsm.build` finds when it is installed).

    /usr/bin/python3 -m venv --system-site-packages .venv
    .venv/bin/pip install --no-build-isolation .
    .venv/bin/pip install --no-build-isolation python/builder   # optional: fsm.build (GPL)

Works offline with Debian 12's packages (cmake, g++, pybind11-dev, libeigen3-dev, libccd-dev,
python3-dev, python3-numpy, python3-setuptools, python3-wheel). The version comes from
CMakeLists.txt, so C++ and Python share one number.
"""
import sys
from pathlib import Path

from setuptools import setup

sys.path.insert(0, str(Path(__file__).resolve().parent / "python"))
from cmake_extension import CMakeBuild, CMakeExtension, version  # noqa: E402

setup(
    version=version(),
    packages=["fsm"],
    package_dir={"": "python"},
    ext_modules=[CMakeExtension("fsm._fsm", "_fsm", "FSM_PYTHON_PACKAGE_DIR", builder=False)],
    cmdclass={"build_ext": CMakeBuild},
    zip_safe=False,
)
