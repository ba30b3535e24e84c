"""Haptics bindings: scripted devices, Python-defined devices, the servo loop offline."""

import numpy as np
import pytest

import fsm


def block_scene(model):
    sim = fsm.Simulation(model)
    solver = fsm.ContactSolver(sim)
    tool = solver.add_instrument(fsm.Instrument(fsm.SphereShape(0.003), fsm.Pose((0.01, 0.01, 0.02))))
    return sim, solver, tool


def probe():
    return [fsm.Waypoint(0.0, (0.01, 0.01, 0.016)), fsm.Waypoint(0.4, (0.01, 0.01, 0.011))]


def test_scripted_device_interpolates_and_records():
    d = fsm.ScriptedHapticDevice(probe(), fsm.DeviceLimits(max_force=0.5))
    s = d.state_at(0.2)
    assert np.allclose(s.position, (0.01, 0.01, 0.0135))
    assert np.allclose(s.linear_velocity, (0, 0, -0.0125))
    assert d.duration == pytest.approx(0.4)
    f = d.apply_force((0.0, 0.0, 3.0))
    assert np.allclose(f, (0, 0, 0.5))  # clamped
    rec = d.forces()
    assert rec.shape == (1, 4) and rec[0, 3] == pytest.approx(0.5)
    assert "scripted" in fsm.device_names()
    with pytest.raises(fsm.Error, match="valid names"):
        fsm.make_device("no-such-device")
    with pytest.raises(fsm.Error):
        fsm.ScriptedHapticDevice([fsm.Waypoint(1.0, (0, 0, 0)), fsm.Waypoint(0.5, (0, 0, 0))])


def test_servo_loop_offline_presses_the_block(block):
    sim, solver, tool = block_scene(block)
    d = fsm.ScriptedHapticDevice(probe())
    loop = fsm.ServoLoop(sim, solver, tool, d)
    loop.run_fast(0.8, d)
    st = loop.stats()
    assert st.ticks == 800 and st.steps == 800
    assert st.diverged_steps == 0 and st.unconverged_solves == 0
    assert st.energy_gain_retries == 0 and st.largest_energy_gain < sim.energy_gain_limit
    f = d.forces()
    assert f[:, 3].max() > 0.01  # pushed up, out of the tissue
    # The tissue's largest push on the instrument, over every step (N).
    assert 0.01 < st.peak_tissue_force < 10
    assert np.all(np.isfinite(f))
    assert len(loop.step_times()) == 800


def test_python_device_drives_the_loop(block):
    class Down(fsm.HapticDevice):
        def __init__(self):
            super().__init__()
            self.forces = []

        def name(self):
            return "down"

        def limits(self):
            return fsm.DeviceLimits(max_force=1.0)

        def read(self, t):
            return fsm.DeviceState(t, (0.01, 0.01, 0.016 - 0.0125 * min(t, 0.4)))

        def apply_force(self, f):
            self.forces.append(np.array(f))

    sim, solver, tool = block_scene(block)
    d = Down()
    loop = fsm.ServoLoop(sim, solver, tool, d)
    loop.run_fast(0.6, d)
    assert len(d.forces) == 601  # every tick, plus the zero of stop
    assert max(f[2] for f in d.forces) > 0.01
    assert np.allclose(d.forces[-1], 0)
