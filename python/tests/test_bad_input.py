"""Bad input from Python (issue 13): every case is an fsm.Error naming the argument and the
reason (or a reported status where the C++ step reports one), never a crash, a silent NaN or an
exception of another kind."""
import math
import os

import numpy as np
import pytest

import fsm

NAN = float("nan")


def test_lattice_cell_counts_that_overflow_are_refused():
    for cells in [(2**31 - 1, 1, 1), (100000, 100000, 100000), (2000, 2000, 2000)]:
        with pytest.raises(fsm.Error, match=r"more vertices or tetrahedra than an Index"):
            fsm.make_cube_lattice((0, 0, 0), cells, 0.001)
    with pytest.raises(fsm.Error, match="at least one cell"):
        fsm.make_cube_lattice((0, 0, 0), (-1, 3, 3), 0.001)
    with pytest.raises(fsm.Error, match="spacing must be positive and finite"):
        fsm.make_cube_lattice((0, 0, 0), (3, 3, 3), NAN)


def test_structure_views_are_read_only_and_setters_check(block):
    with pytest.raises(ValueError, match="read-only"):
        block.links[0, 0] = 10**6
    with pytest.raises(ValueError, match="read-only"):
        block.node_regions[0] = 99
    with pytest.raises(ValueError, match="read-only"):
        block.fixed[0] = 7
    regions = np.array(block.node_regions)
    regions[3] = 5
    with pytest.raises(fsm.Error, match=r"node_regions: entry 3 is 5, not a region in \[0, 1\)"):
        block.node_regions = regions
    flags = np.array(block.fixed)
    flags[2] = 2
    with pytest.raises(fsm.Error, match="fixed: entry 2 is 2; a fixed flag is 0 or 1"):
        block.fixed = flags
    # A valid whole-array assignment still works, and the model still steps.
    flags[2] = 1
    block.fixed = flags
    sim = fsm.Simulation(block)
    assert sim.step(1e-3).advanced


def test_values_edited_through_views_are_checked_before_use(block):
    block.masses[5] = 0.0
    with pytest.raises(fsm.Error, match="node 5 .*mass 0 kg must be positive"):
        fsm.Simulation(block)
    block.masses[5] = 1e-3
    block.radii[0] = NAN
    with pytest.raises(fsm.Error, match="node 0 .*radius nan m must be positive"):
        fsm.ContactSolver(block)


def test_a_nan_state_is_a_reported_status_never_a_nan_model(block):
    sim = fsm.Simulation(block)
    sim.external_forces[0, 0] = NAN
    report = sim.step(1e-3)
    assert not report.advanced and report.status == "invalid_input"
    assert np.isfinite(sim.model.positions).all()
    sim.external_forces[0, 0] = 0
    sim.model.positions[3, 1] = NAN
    report = sim.step(1e-3)
    assert not report.advanced and report.status == "invalid_input"
    assert np.isfinite(sim.model.positions).all()
    assert sim.step(NAN).status == "invalid_time_step"
    assert sim.step(-1e-3).status == "invalid_time_step"


def test_run_refuses_negative_counts_and_bad_steps(block):
    sim = fsm.Simulation(block)
    with pytest.raises(fsm.Error, match="steps: is -5"):
        sim.run(-5, 1e-3)
    for dt in (NAN, -1e-3, 0.0, math.inf):
        with pytest.raises(fsm.Error, match="dt: is .* s; it must be positive and finite"):
            sim.run(10, dt)
    assert sim.run(3, 1e-3) == 3


def _uterus_like_skin():
    model = fsm.SphereModel()
    r = model.add_region("b", fsm.Material(density=1050, youngs_modulus=13150))
    fsm.add_tetrahedral_part(model, fsm.make_cube_lattice((0, 0, 0), (2, 2, 2), 0.005), r, 0.0025)
    return model


def test_queries_refuse_nan_and_zero_arguments():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    f = np.array([[0, 1, 2]], dtype=np.int32)
    bvh = fsm.TriangleBvh(v, f)
    with pytest.raises(fsm.Error, match="direction: must be a finite, non-zero direction"):
        bvh.ray_cast((0.2, 0.2, 1), (0, 0, 0))
    with pytest.raises(fsm.Error, match="direction: must be a finite, non-zero direction"):
        bvh.ray_cast((0.2, 0.2, 1), (NAN, 0, -1))
    with pytest.raises(fsm.Error, match="origin: is not finite"):
        bvh.ray_cast((NAN, 0.2, 1), (0, 0, -1))
    with pytest.raises(fsm.Error, match="max_distance: is nan"):
        bvh.ray_cast((0.2, 0.2, 1), (0, 0, -1), NAN)
    assert bvh.ray_cast((0.2, 0.2, 1), (0, 0, -1)).face == 0
    with pytest.raises(fsm.Error, match="direction"):
        fsm.intersect_ray_triangle((0, 0, 1), (0, 0, 0), v[0], v[1], v[2])
    with pytest.raises(fsm.Error, match="radius: is -1"):
        bvh.faces_near((0, 0, 0), -1.0)
    bad = v.copy()
    bad[1, 1] = NAN
    with pytest.raises(fsm.Error, match="vertices: is not finite"):
        bvh.refit(bad)
    with pytest.raises(fsm.Error, match="centre: is not finite"):
        fsm.shape_contact(fsm.SphereShape(0.01), fsm.Pose(), (NAN, 0, 0), 0.001)


def test_skin_refuses_nan_positions(tmp_path):
    model = fsm.load_model(os.path.join(os.environ["FSM_SOURCE_DIR"], "tests", "data",
                                        "model_v1_ovary_ligament.fsm"))
    x = np.array(model.spheres.positions)
    assert np.isfinite(model.skin.evaluate(x)).all()
    x[4, 2] = NAN
    with pytest.raises(fsm.Error, match="positions: is not finite"):
        model.skin.evaluate(x)


def _loop(block, device, options=None):
    sim = fsm.Simulation(block)
    contacts = fsm.ContactSolver(sim)
    k = contacts.add_instrument(fsm.Instrument(fsm.SphereShape(0.002)))
    return fsm.ServoLoop(sim, contacts, k, device, options or fsm.ServoOptions())


def test_servo_run_length_must_be_finite_and_non_negative(block):
    device = fsm.ScriptedHapticDevice([fsm.Waypoint(0, (0, 0, 0.03), (1, 0, 0, 0), 0)])
    loop = _loop(block, device)
    for seconds in (NAN, -1.0, math.inf, 1e30):
        with pytest.raises(fsm.Error, match="seconds must be finite, non-negative"):
            loop.run_fast(seconds, device)
    loop.run_fast(0.01, device)
    assert loop.stats().ticks == 10


def test_an_exception_in_a_python_device_reaches_the_caller(block):
    class Broken(fsm.HapticDevice):
        def __init__(self):
            super().__init__()
            self.calls = 0

        def name(self):
            return "broken"

        def read(self, t):
            self.calls += 1
            if self.calls == 3:
                raise ValueError("the tracker lost the marker")
            return fsm.DeviceState(t, (0, 0, 0.03))

        def apply_force(self, f):
            pass

    device = Broken()
    loop = _loop(block, device)
    with pytest.raises(ValueError, match="the tracker lost the marker") as info:
        loop.run_fast(0.01, device)
    assert any("HapticDevice.read() inside ServoLoop.run_fast" in n
               for n in getattr(info.value, "__notes__", []))
    assert device.calls > 3  # the loop went on (with the device at rest) to its end

    class WrongType(fsm.HapticDevice):
        def name(self):
            return "wrong"

        def read(self, t):
            return (0, 0, 0)

    device = WrongType()
    loop = _loop(block, device)
    with pytest.raises(TypeError, match="read\\(\\) must return a DeviceState"):
        loop.run_fast(0.005, device)
