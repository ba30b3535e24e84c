"""setuptools glue shared by the two distributions of this repository (setup.py: ``fsm``, BSD;
python/builder/setup.py: ``fsm-builder``, GPL): CMake configures the whole project and builds one
extension target into the package folder setuptools expects. Offline, with Debian's packages."""
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Extension
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent.parent


def version():
    """The project's version, from the top-level CMakeLists.txt (one number for C++ and Python)."""
    return re.search(r"project\(\s*fsm\s+VERSION\s+([0-9.]+)",
                     (ROOT / "CMakeLists.txt").read_text()).group(1)


def cmake_build_dir(build_temp, named=None):
    """The CMake tree to configure and keep: `named` (FSM_CMAKE_BUILD_DIR; a tree of its own, which
    both distributions may share so the builder's reuses the runtime's objects; relative to the
    repository's root) or, by default, setuptools' scratch folder `build_temp`/cmake."""
    return (ROOT / named if named else Path(build_temp) / "cmake").resolve()


class CMakeExtension(Extension):
    """An extension that CMake builds: `target` is its CMake target, `package_dir_var` the cache
    variable that says where CMake puts it, `builder` whether the GPL builder is configured."""

    def __init__(self, name, target, package_dir_var, builder):
        super().__init__(name, sources=[])
        self.target = target
        self.package_dir_var = package_dir_var
        self.builder = builder


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        package_dir = Path(self.get_ext_fullpath(ext.name)).parent.resolve()
        build_dir = cmake_build_dir(self.build_temp, os.environ.get("FSM_CMAKE_BUILD_DIR"))
        configure = [
            "cmake", "-S", str(ROOT), "-B", str(build_dir),
            "-DCMAKE_BUILD_TYPE=Release",
            "-DFSM_BUILD_TESTS=OFF", "-DFSM_BUILD_BENCHMARKS=OFF", "-DFSM_BUILD_EXAMPLES=OFF",
            "-DFSM_BUILD_PYTHON=ON", f"-DFSM_BUILD_BUILDER={'ON' if ext.builder else 'OFF'}",
            f"-DPython_EXECUTABLE={sys.executable}",
            f"-D{ext.package_dir_var}={package_dir}",
        ]
        if shutil.which("ninja"):
            configure += ["-G", "Ninja"]
        subprocess.check_call(configure)
        subprocess.check_call(["cmake", "--build", str(build_dir), "--target", ext.target,
                               "-j", str(os.cpu_count() or 2)])
