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
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).parent.resolve()
VERSION = re.search(r"project\(\s*fsm\s+VERSION\s+([0-9.]+)",
                    (ROOT / "CMakeLists.txt").read_text()).group(1)


class CMakeExtension(Extension):
    def __init__(self, name):
        super().__init__(name, sources=[])


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        package_dir = Path(self.get_ext_fullpath(ext.name)).parent.resolve()
        build_dir = Path(self.build_temp).resolve() / "cmake"
        configure = [
            "cmake", "-S", str(ROOT), "-B", str(build_dir),
            "-DCMAKE_BUILD_TYPE=Release",
            "-DFSM_BUILD_TESTS=OFF", "-DFSM_BUILD_BENCHMARKS=OFF", "-DFSM_BUILD_EXAMPLES=OFF",
            "-DFSM_BUILD_PYTHON=ON", "-DFSM_BUILD_BUILDER=OFF",
            f"-DPython_EXECUTABLE={sys.executable}",
            f"-DFSM_PYTHON_PACKAGE_DIR={package_dir}",
        ]
        if shutil.which("ninja"):
            configure += ["-G", "Ninja"]
        subprocess.check_call(configure)
        # _fsm only: the BSD runtime. The GPL builder is python/builder's distribution.
        subprocess.check_call(["cmake", "--build", str(build_dir), "--target", "_fsm",
                               "-j", str(os.cpu_count() or 2)])


setup(
    version=VERSION,
    packages=["fsm"],
    package_dir={"": "python"},
    ext_modules=[CMakeExtension("fsm._fsm")],
    cmdclass={"build_ext": CMakeBuild},
    zip_safe=False,
)
