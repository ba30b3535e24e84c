"""Built models from Python: fsm.build (the GPL builder module), model files, the skin."""
import os

import numpy as np
import pytest

import fsm

build = pytest.importorskip("fsm.build", reason="the builder module (fsm._fsm_build) was not built")
SOURCE = os.environ.get("FSM_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
SCENE = os.path.join(SOURCE, "data", "uterus", "uterus.json")


@pytest.fixture(scope="module")
def uterus():
    return build.build_model(SCENE)


def test_build_the_default_data_set(uterus):
    model, report, table = uterus
    assert [p.name for p in model.parts][:2] == ["body", "fibroid"]
    assert abs(model.part("body").num_nodes - 517) <= 0.15 * 517
    assert report["spheres"] == model.spheres.num_nodes
    assert report["parts"][0]["quality"]["fraction_q_1_3"] > 0.95
    assert "body" in table and "total:" in table
    assert model.part("tube_left").topology == fsm.Topology.axis
    # A part's slice selects its spheres in the node arrays.
    body = model.spheres.positions[model.part("body").nodes]
    assert body.shape == (model.part("body").num_nodes, 3)


def test_skin_reproduces_rest_and_follows_a_translation(uterus):
    model = uterus[0]
    rest = model.spheres.rest_positions
    assert np.abs(model.skin.evaluate(rest) - model.skin.vertices).max() < 1e-15
    shift = np.array([0.01, -0.02, 0.03])
    assert np.allclose(model.skin.evaluate(rest + shift), model.skin.vertices + shift, atol=1e-14)
    assert model.skin.faces.dtype == np.int32 and model.skin.faces.shape[1] == 3
    assert sum(s.num_vertices for s in model.skin.surfaces) == model.skin.num_vertices
    with pytest.raises(fsm.Error, match="positions"):
        model.skin.evaluate(rest[:10])


def test_model_file_round_trip_and_simulation(uterus, tmp_path):
    model = uterus[0]
    path = tmp_path / "uterus.fsm"
    fsm.save_model(str(path), model)
    loaded = fsm.load_model(str(path))
    assert loaded.spheres.num_links == model.spheres.num_links
    assert np.array_equal(loaded.spheres.rest_positions, model.spheres.rest_positions)
    assert np.array_equal(loaded.skin.vertices, model.skin.vertices)
    sim = fsm.Simulation(loaded.spheres)
    assert sim.run(50, 1e-3) == 50
    path.write_bytes(path.read_bytes()[:100])
    with pytest.raises(fsm.Error, match="truncated"):
        fsm.load_model(str(path))


def test_builder_errors_and_mesh_checks(tmp_path):
    with pytest.raises(fsm.Error, match="cannot open the scene file"):
        build.build_model(str(tmp_path / "missing.json"))
    (tmp_path / "bad.json").write_text('{"format": "fsm-scene", "version": 9, "parts": []}')
    with pytest.raises(fsm.Error, match="newer than this builder"):
        build.build_model(str(tmp_path / "bad.json"))
    v, f = build.read_mesh(os.path.join(SOURCE, "data", "uterus", "ovary_left.obj"), 0.01)
    report = build.inspect_mesh(v, f)
    assert report["bounds_a_volume"] and report["boundary_edges"] == 0
    assert report["volume"] == pytest.approx(0.861e-6, rel=0.01)
    report = build.inspect_mesh(v, f[:-3])
    assert report["boundary_edges"] > 0 and not report["bounds_a_volume"]


def test_read_mesh_takes_glb_nodes(tmp_path):
    """fsm.build.read_mesh reads glTF nodes (the tutorial's two-node GLB), under their transforms."""
    import subprocess
    import sys

    glb = tmp_path / "organ.glb"
    subprocess.run([sys.executable, os.path.join(SOURCE, "examples", "tutorial", "make_organ_glb.py"),
                    str(glb)], check=True, capture_output=True)
    organ_v, organ_f = build.read_mesh(str(glb), 1.0, ["organ"])
    duct_v, duct_f = build.read_mesh(str(glb), 1.0, ["duct"])
    all_v, all_f = build.read_mesh(str(glb))
    assert len(all_f) == len(organ_f) + len(duct_f)
    np.testing.assert_allclose(organ_v.max(axis=0), (0.030, 0.020, 0.015), rtol=1e-6)
    # The duct's node translates it 50 mm along x: it spans 25-75 mm.
    np.testing.assert_allclose([duct_v[:, 0].min(), duct_v[:, 0].max()], [0.025, 0.075], rtol=1e-6)
    with pytest.raises(fsm.Error, match="no such node"):
        build.read_mesh(str(glb), 1.0, ["liver"])
