"""Cutting, tearing and grasping from Python (fsm.Blade, Simulation.cut, tear strains,
fsm.Grasper, fsm.CutSurface)."""
import math
import os

import numpy as np
import pytest

import fsm


def bar(law="links", tear_strain=math.inf, cells=(6, 2, 2)):
    """A bar of 5 mm spheres along x, held at x = 0."""
    tissue = fsm.Material(density=1000, youngs_modulus=3000, viscosity=5, tear_strain=tear_strain)
    model = fsm.SphereModel()
    region = model.add_region("bar", tissue)
    fsm.add_tetrahedral_part(model, fsm.make_cube_lattice((0, 0, 0), cells, 0.005), region, 0.0025)
    if law == "continuum":
        model.set_region_law(region, fsm.ForceLaw.continuum)
    for i in np.flatnonzero(model.rest_positions[:, 0] < 1e-9):
        model.set_fixed(int(i))
    return model


def through(x):
    return fsm.Blade((x, -0.002, 0.013), (x, 0.012, 0.013), (x, -0.002, -0.003),
                     (x, 0.012, -0.003))


@pytest.mark.parametrize("law", ["links", "continuum"])
def test_a_cut_bar_falls_apart_and_keeps_its_mass(law):
    sim = fsm.Simulation(bar(law), gravity=(0, 0, -9.81))
    mass = sim.model.masses.sum()
    blade = through(0.0175)
    change = sim.cut(blade)
    assert change.links_cut > 0 and change.tetrahedra_cut > 0
    assert change.pieces == 2 and change.loose_pieces == 1
    assert len(sim.broken_links) == change.links_cut
    assert sim.model.num_broken_links == change.links_cut
    assert sim.model.masses.sum() == mass
    x = sim.model.positions
    for l in np.flatnonzero(sim.model.link_intact):
        i, j = sim.model.links[l]
        assert not blade.crosses(x[i], x[j])
    loose = sim.model.rest_positions[:, 0] > 0.0175
    z0 = x[loose, 2].mean()
    assert sim.run(200, 1e-3) == 200
    drop = 9.81 * 1e-6 * 200 * 201 / 2  # implicit Euler under gravity
    assert math.isclose(z0 - sim.model.positions[loose, 2].mean(), drop, rel_tol=1e-3)


def test_bad_blades_and_thresholds():
    with pytest.raises(fsm.Error, match="zero length"):
        fsm.Blade((0, 0, 0), (0, 0, 0), (0, 0, 1), (1, 0, 1))
    with pytest.raises(fsm.Error, match="not finite"):
        fsm.Blade((math.nan, 0, 0), (1, 0, 0), (0, 0, 1), (1, 0, 1))
    with pytest.raises(fsm.Error, match="tear_strain"):
        fsm.Material(density=1000, youngs_modulus=3000, tear_strain=-0.1)
    sim = fsm.Simulation(bar())
    t = np.array(sim.tear_strains)
    t[0] = math.nan
    with pytest.raises(fsm.Error, match="link 0"):
        sim.tear_strains = t
    assert math.isinf(sim.tear_strains[0])  # unchanged


def test_a_pulled_bar_tears_where_its_material_says():
    sim = fsm.Simulation(bar(tear_strain=0.3, cells=(6, 1, 1)), gravity=(0, 0, 0), drag=5)
    end = sim.model.rest_positions[:, 0] > 0.0299
    sim.external_forces[end] = (0.02, 0, 0)
    torn = 0
    for _ in range(3000):
        r = sim.step(1e-3)
        assert r.advanced
        torn += r.torn.links_torn
        if torn:
            assert len(sim.broken_links) == r.torn.links_torn
            break
    assert torn > 0
    m = sim.model
    intact = m.link_intact.astype(bool)
    length = np.linalg.norm(m.positions[m.links[:, 1]] - m.positions[m.links[:, 0]], axis=1)
    assert np.all(length[intact] <= 1.3 * m.rest_lengths[intact] * (1 + 1e-12))


def test_grasp_lift_and_release():
    model = bar(cells=(4, 4, 2))
    for i in np.flatnonzero(model.rest_positions[:, 2] < 1e-9):  # the bottom held too
        model.set_fixed(int(i))
    sim = fsm.Simulation(model, gravity=(0, 0, 0), drag=5)
    grasper = fsm.Grasper(sim, 0.6)
    pose = fsm.Pose(position=(0.004, 0.010, 0.010))
    assert grasper.update(sim, pose, 0.6).grasped == 0
    event = grasper.update(sim, pose, 0.05)
    assert event.grasped > 0 and grasper.holding
    held = list(grasper.held)
    z0 = sim.model.positions[held, 2].copy()
    for s in range(300):
        grasper.update(sim, pose, 0.05, velocity=(0, 0, 0.01))
        assert sim.step(1e-3).advanced
        pose = fsm.Pose(position=pose.position + np.array([0, 0, 1e-5]))
    assert np.all(sim.model.positions[held, 2] - z0 > 0.0028)
    assert grasper.wrench(sim).force[2] < 0  # the tissue pulls the jaws down
    assert grasper.update(sim, pose, 0.5).released == len(held)
    assert not grasper.holding
    with pytest.raises(fsm.Error, match="closed"):
        fsm.Grasper(sim, 0.05)
    with pytest.raises(fsm.Error, match="stiffness"):
        fsm.GrasperOptions(stiffness=-1)


def test_cut_surface_hides_the_skin_across_a_cut_ligament():
    source = os.environ.get("FSM_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
    tm = fsm.load_model(os.path.join(source, "tests", "data", "model_v1_ovary_ligament.fsm"))
    sim = fsm.Simulation(tm.spheres)
    surface = fsm.CutSurface(sim.model, tm.skin)
    assert surface.num_hidden == 0
    # A blade across the middle of the ligament's chain, perpendicular to it.
    part = tm.part("ligament_left")
    links = sim.model.links
    l = part.first_link + part.num_links // 2
    a, b = sim.model.positions[links[l]]
    mid, d = (a + b) / 2, (b - a) / np.linalg.norm(b - a)
    u = np.cross(d, (1, 0, 0) if abs(d[0]) < 0.9 else (0, 1, 0))
    u /= np.linalg.norm(u)
    w = np.cross(d, u)
    blade = fsm.Blade(mid - 0.01 * u - 0.01 * w, mid + 0.01 * u - 0.01 * w,
                      mid - 0.01 * u + 0.01 * w, mid + 0.01 * u + 0.01 * w)
    vertices = tm.skin.evaluate(sim.model.positions)
    change = sim.cut(blade)
    assert change.links_cut >= 1 and not sim.model.link_intact[l]
    assert change.pieces >= 2
    surface.add_cut(blade, vertices)
    surface.update(sim.model)
    assert surface.num_hidden > 0
    faces = surface.skin_faces
    for f in range(len(faces)):
        if surface.hidden(f):
            assert faces[f, 0] == faces[f, 1] == faces[f, 2]
        else:
            assert np.array_equal(faces[f], tm.skin.faces[f])
    assert surface.walls.shape == (0, 3)  # a version 1 file has no tetrahedra
