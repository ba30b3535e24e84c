"""Builds the fsm-builder distribution (GPL-3.0-or-later): the fsm_builder package and its CGAL
extension _fsm_build, from the same CMake project as the runtime.

    .venv/bin/pip install --no-build-isolation .               # the runtime, fsm (BSD-3-Clause)
    .venv/bin/pip install --no-build-isolation python/builder  # this, fsm-builder (GPL)

Works offline with Debian 12's packages (as the runtime, plus libcgal-dev, libgmp-dev,
libmpfr-dev, nlohmann-json3-dev). The version comes from the top-level CMakeLists.txt.
"""
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

HERE = Path(__file__).parent.resolve()
ROOT = HERE.parent.parent
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
            "-DFSM_BUILD_PYTHON=ON", "-DFSM_BUILD_BUILDER=ON",
            f"-DPython_EXECUTABLE={sys.executable}",
            f"-DFSM_PYTHON_BUILDER_DIR={package_dir}",
        ]
        if shutil.which("ninja"):
            configure += ["-G", "Ninja"]
        subprocess.check_call(configure)
        subprocess.check_call(["cmake", "--build", str(build_dir), "--target", "_fsm_build",
                               "-j", str(os.cpu_count() or 2)])


setup(
    version=VERSION,
    packages=["fsm_builder"],
    ext_modules=[CMakeExtension("fsm_builder._fsm_build")],
    cmdclass={"build_ext": CMakeBuild},
    zip_safe=False,
)
