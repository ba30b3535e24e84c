"""setup.py's choice of CMake tree (python/cmake_extension.py): the packaging test
(tests/packaging/pip_install.sh) names one, so the default is checked here."""
import importlib.util
import os
from pathlib import Path

SOURCE = os.environ.get("FSM_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
# Loaded from its file, not through sys.path: python/ also holds the fsm package's sources, which
# would then shadow the built one for the tests (and subprocesses) that follow.
_spec = importlib.util.spec_from_file_location(
    "cmake_extension", os.path.join(SOURCE, "python", "cmake_extension.py"))
_module = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_module)
ROOT, cmake_build_dir = _module.ROOT, _module.cmake_build_dir


def test_default_tree_is_in_setuptools_scratch_folder(tmp_path):
    temp = tmp_path / "build-python" / "temp"
    assert cmake_build_dir(str(temp)) == (temp / "cmake").resolve()
    assert cmake_build_dir(str(temp), "") == (temp / "cmake").resolve()  # set but empty


def test_named_tree_is_taken_from_the_repository_root_or_as_given(tmp_path, monkeypatch):
    # The same relative name from either distribution's folder (pip runs each from its own) gives
    # one tree.
    monkeypatch.chdir(tmp_path)
    assert cmake_build_dir("ignored", "build-pip") == (ROOT / "build-pip").resolve()
    assert ROOT == Path(SOURCE).resolve()
    assert cmake_build_dir("ignored", str(tmp_path / "tree")) == (tmp_path / "tree").resolve()
