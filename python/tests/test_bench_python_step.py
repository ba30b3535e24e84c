"""bench/python_step.py (docs/benchmarks.md, "From Python") runs on a small built model and
measures what it says: the three step loops ran, and the ball touched the tissue. No timing is
asserted."""
import json
import os
import subprocess
import sys

import pytest

import fsm

build = pytest.importorskip("fsm.build", reason="the builder module (fsm._fsm_build) was not built")
SOURCE = os.environ.get("FSM_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))


def test_python_step_benchmark_runs(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(os.path.join(SOURCE, "validation"))
    import scenes

    box = str(tmp_path / "box.off")
    scenes.write_box_off(box)
    scene = str(tmp_path / "block.json")
    scenes.write_scene(scene, box, "tetrahedral", 2.5, scenes.LINEAR)
    tissue, _, _ = build.build_model(scene)
    model = str(tmp_path / "block.fsm")
    fsm.save_model(model, tissue)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    out = subprocess.run([sys.executable, os.path.join(SOURCE, "bench", "python_step.py"), model,
                          "--steps", "20", "--repeats", "2"], capture_output=True, text=True,
                         env=env, check=True)
    r = json.loads(out.stdout)
    assert r["spheres"] == tissue.spheres.num_nodes
    assert len(r["runs_us"]["sim_run"]) == len(r["runs_us"]["python_loop"]) == 2
    assert r["sim_run_us"] > 0 and r["python_loop_us"] > 0 and r["script_step_us"] > 0
    assert r["probe_contacts"] > 0  # the ball pressed into the block
