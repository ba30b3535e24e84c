"""ParaView output (fsm.export, through meshio): what is written reads back the same."""
import os
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import fsm

meshio = pytest.importorskip("meshio", reason="python3-meshio is not installed")
import fsm.export  # noqa: E402


def test_series_of_a_block_reads_back(block, tmp_path):
    sim = fsm.Simulation(block)
    sim.external_forces[int(np.argmax(block.rest_positions[:, 2]))] = (0, 0, -0.05)
    series = fsm.export.VtkSeries(tmp_path / "out", sim.model)
    states = []
    for k in range(3):
        for _ in range(10):
            assert sim.step(1e-3).advanced
        f = sim.internal_forces()
        series.write(sim.time, sim.model.positions, sim.model.velocities, f)
        states.append((sim.time, sim.model.positions.copy(), sim.model.velocities.copy(), f))
    # The index lists each state once (no skin: spheres only), times increasing.
    root = ET.parse(series.series_path).getroot()
    sets = root.findall("./Collection/DataSet")
    assert [float(d.get("timestep")) for d in sets] == [s[0] for s in states]
    assert {d.get("part") for d in sets} == {"0"}
    last = meshio.read(os.path.join(tmp_path, "out", sets[-1].get("file")))
    t, x, v, f = states[-1]
    np.testing.assert_array_equal(last.points, x)
    np.testing.assert_array_equal(last.point_data["velocity"], v)
    np.testing.assert_array_equal(last.point_data["force"], f)
    np.testing.assert_array_equal(last.point_data["radius"], block.radii)
    np.testing.assert_array_equal(last.point_data["fixed"], block.fixed.astype(np.int32))
    blocks = {c.type: c.data for c in last.cells}
    np.testing.assert_array_equal(blocks["line"], block.links)
    np.testing.assert_array_equal(blocks["tetra"], block.tetrahedra)
    kinds = np.concatenate(last.cell_data["kind"])
    assert (kinds == 0).sum() == block.num_links and (kinds == 1).sum() == block.num_tetrahedra
    # The states differ: the block moves under the load.
    first = meshio.read(os.path.join(tmp_path, "out", sets[0].get("file")))
    assert np.abs(first.points - last.points).max() > 1e-7


def test_series_refuses_bad_input(block, tmp_path):
    series = fsm.export.VtkSeries(tmp_path, block)
    series.write(0.0)
    with pytest.raises(fsm.Error, match="after"):
        series.write(0.0)
    with pytest.raises(fsm.Error, match="positions"):
        series.write(1.0, positions=np.zeros((3, 3)))
    with pytest.raises(fsm.Error, match="NaN"):
        series.write(1.0, velocities=np.full((block.num_nodes, 3), np.nan))
    with pytest.raises(fsm.Error, match="name"):
        fsm.export.VtkSeries(tmp_path, block, name="a/b")


def test_tissue_model_series_has_the_render_surface(tmp_path):
    # The builder is the separate GPL distribution (fsm-builder): a BSD-only install has no
    # fsm.build, and this test (which needs a built model with a skin) is skipped there.
    build = pytest.importorskip("fsm.build", reason="the builder module (fsm._fsm_build) was not built")
    source = os.environ.get("FSM_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
    model, _, _ = build.build_model(os.path.join(source, "data", "uterus", "uterus.json"))
    series = fsm.export.VtkSeries(tmp_path, model)
    moved = model.spheres.positions + (0.0, 0.0, 0.01)
    series.write(0.5, positions=moved, surface=model.skin.evaluate(moved))
    root = ET.parse(series.series_path).getroot()
    files = {d.get("part"): d.get("file") for d in root.findall("./Collection/DataSet")}
    surface = meshio.read(os.path.join(tmp_path, files["1"]))
    np.testing.assert_allclose(surface.points, model.skin.vertices + (0.0, 0.0, 0.01), atol=1e-12)
    np.testing.assert_array_equal(surface.cells[0].data, model.skin.faces)
    which = surface.cell_data["surface"][0]
    for k, s in enumerate(model.skin.surfaces):
        assert (which[s.first_face : s.first_face + s.num_faces] == k).all()
