"""Simulation from Python: stepping, integrators by name or class, energy, errors, physics."""
import math
import threading
import time

import numpy as np
import pytest

import fsm


def test_round_trip_build_step_read_write(block):
    sim = fsm.Simulation(block, integrator="implicit_euler")
    top = int(np.argmax(sim.model.rest_positions[:, 2] + sim.model.rest_positions[:, 0]))
    sim.external_forces[top] = (0.0, 0.0, -0.02)
    reports = [sim.step(1e-3) for _ in range(200)]
    assert all(r.status == "ok" for r in reports)
    x = sim.model.positions
    assert x[top, 2] < sim.model.rest_positions[top, 2]
    # The fixed layer did not move, the input model (copied in) did not change.
    fixed = sim.model.fixed.astype(bool)
    assert np.array_equal(x[fixed], sim.model.rest_positions[fixed])
    assert np.array_equal(block.positions, block.rest_positions)
    # Writing state from Python, then stepping, continues from what was written.
    sim.model.velocities[:] = 0.0
    sim.model.positions[top] += (0, 0, 0.001)
    assert sim.step(1e-3).advanced
    e = sim.energy()
    assert e.total <= e.budget * (1 + 1e-9)
    assert math.isclose(sim.time, 0.201, rel_tol=1e-12)


def test_integrators_by_name_and_by_class(block):
    for name in fsm.integrator_names():
        sim = fsm.Simulation(block, integrator=name)
        assert sim.integrator == name
    ie = fsm.ImplicitEulerIntegrator(solver="eigen_ldlt")
    sim = fsm.Simulation(block, integrator=ie)
    assert sim.integrator == "implicit_euler"
    assert math.isinf(sim.stable_time_step)
    sim.set_integrator(fsm.SymplecticEulerIntegrator())
    assert 0 < sim.stable_time_step < 1e-3
    with pytest.raises(fsm.Error, match="valid names: improved_euler, heun"):
        fsm.Simulation(block, integrator="rk4")
    with pytest.raises(fsm.Error, match="solver 'cholmod'"):
        fsm.ImplicitEulerIntegrator(solver="cholmod")
    with pytest.raises(fsm.Error, match="damping 'viscous'"):
        fsm.Simulation(block, damping="viscous")
    with pytest.raises(fsm.Error, match="preconditioner 'ilu'"):
        fsm.ImplicitEulerIntegrator(preconditioner="ilu")
    assert fsm.ImplicitEulerIntegrator().velocity_tolerance == 1e-9
    assert fsm.ImplicitEulerIntegrator(velocity_tolerance=0).velocity_tolerance == 0
    for bad in (-1e-9, float("nan"), float("inf")):
        with pytest.raises(fsm.Error, match="velocity_tolerance"):
            fsm.ImplicitEulerIntegrator(velocity_tolerance=bad)


def test_a_solve_cut_off_at_its_cap_is_reported(block):
    """StepReport.unconverged_solves counts the sub-steps whose CG stopped at max_iterations short
    of its tolerance; converged solves count none."""
    capped = fsm.Simulation(block, integrator=fsm.ImplicitEulerIntegrator(
        tolerance=1e-12, max_iterations=2))
    full = fsm.Simulation(block, integrator=fsm.ImplicitEulerIntegrator())
    for _ in range(10):
        r = capped.step(5e-3)  # the checks may reject a truncated step: every attempt counts
        assert r.solver_iterations == 2 * r.substeps and r.unconverged_solves == r.substeps
        r = full.step(5e-3)
        assert r.advanced and r.unconverged_solves == 0


def test_preconditioners_solve_the_same_step(block):
    """Jacobi and block-Jacobi CG, with and without the extrapolated warm start, reach the same
    states (they change only the path to the solution) and the exact LDLT solve's, to the CG
    tolerance."""
    finals = {}
    for name, ie in [("jacobi", fsm.ImplicitEulerIntegrator(preconditioner="jacobi", tolerance=1e-10)),
                     ("block_jacobi", fsm.ImplicitEulerIntegrator(tolerance=1e-10)),
                     ("no_extrapolation", fsm.ImplicitEulerIntegrator(
                         tolerance=1e-10, extrapolate_warm_start=False)),
                     ("ldlt", fsm.ImplicitEulerIntegrator(solver="eigen_ldlt"))]:
        if name in ("jacobi", "block_jacobi"):
            assert ie.preconditioner == name
        assert ie.extrapolate_warm_start == (name != "no_extrapolation")
        sim = fsm.Simulation(block, integrator=ie)
        for _ in range(50):
            assert sim.step(1e-3).status == "ok"
        finals[name] = sim.model.positions.copy()
    sag = np.abs(finals["ldlt"] - block.positions).max()
    assert sag > 1e-5  # gravity moved it
    for name in ("jacobi", "block_jacobi", "no_extrapolation"):
        assert np.abs(finals[name] - finals["ldlt"]).max() < 1e-6 * sag


def test_divergence_is_reported_and_rolled_back(block):
    sim = fsm.Simulation(block, integrator="symplectic_euler", gravity=(0, 0, 0))
    sim.model.velocities[:] = np.random.default_rng(1).normal(0, 0.05, (block.num_nodes, 3))
    sim.model.velocities[sim.model.fixed.astype(bool)] = 0
    dt = 5 * sim.stable_time_step
    statuses = []
    for _ in range(2000):
        before = sim.model.positions.copy()
        r = sim.step(dt)
        statuses.append(r.status)
        if r.status == "diverged":
            assert np.array_equal(sim.model.positions, before)
            break
    assert "diverged" in statuses
    assert np.all(np.isfinite(sim.model.positions))
    assert sim.step(float("nan")).status == "invalid_time_step"


def test_each_step_is_held_to_the_energy_it_started_with(block):
    """check_step_energy: after the block rings down, an unstable step size is caught at once; the
    cumulative budget alone lets the energy grow many times over first."""
    highest = {}
    for step_check in (True, False):
        sim = fsm.Simulation(block, integrator="symplectic_euler", gravity=(0, 0, 0), drag=50.0,
                             check_step_energy=step_check)
        sim.model.positions[:, 2] *= 1.05  # stretched (not the fixed layer): energy to ring down
        dt = 0.5 * sim.stable_time_step
        start = sim.energy().total
        for _ in range(200000):
            assert sim.step(dt).status == "ok"
            if sim.energy().total < 0.02 * start:
                break
        rest = sim.energy().total
        assert rest < 0.02 * start
        top = rest
        for _ in range(5000):
            r = sim.step(6 * dt)
            if r.status == "diverged":
                break
            top = max(top, r.energy)
        highest[step_check] = top / rest
    assert highest[True] < 10  # measured 6.1 (the floor lets the first steps through)
    assert highest[False] > 5 * highest[True]  # measured 66


def test_energy_gain_is_reported_and_its_strain_checked(block):
    """energy_gain: what a step ended with beyond its start energy and work; an implicit step
    ringing down removes energy, so it is never retried for a gain."""
    sim = fsm.Simulation(block, integrator="implicit_euler", gravity=(0, 0, 0),
                         max_substep_halvings=2)
    sim.model.positions[:, 2] *= 1.05
    reports = [sim.step(1e-3) for _ in range(100)]
    assert all(r.status == "ok" and r.energy_gain_retries == 0 for r in reports)
    gains = np.array([r.energy_gain for r in reports])
    assert np.all(np.isfinite(gains)) and gains.max() <= 1e-12 and gains.min() < 0
    unchecked = fsm.Simulation(block, check_energy=False).step(1e-3)
    assert math.isnan(unchecked.energy_gain)
    for bad in (-0.01, float("nan")):
        with pytest.raises(fsm.Error):
            fsm.Simulation(block, energy_gain_strain=bad)


def test_two_sphere_oscillator_frequency(tissue):
    """q'' = -(2k/m) q: the period measured through the bindings matches 2 pi sqrt(m / 2k)."""
    m, k = 0.001, 500.0
    model = fsm.SphereModel()
    r = model.add_region("pair", tissue)
    model.add_node((0, 0, 0), 0.002, m, r)
    model.add_node((0.01, 0, 0), 0.002, m, r)
    model.add_link(0, 1, k, 0.0)
    model.positions[1, 0] += 1e-4
    sim = fsm.Simulation(model, integrator="symplectic_euler", gravity=(0, 0, 0))
    h = 1e-5
    q = []
    for _ in range(2000):
        sim.step(h)
        q.append(sim.model.positions[1, 0] - sim.model.positions[0, 0] - 0.01)
    q = np.array(q)
    crossings = np.flatnonzero(np.sign(q[:-1]) != np.sign(q[1:]))
    period = 2 * h * np.mean(np.diff(crossings))
    assert period == pytest.approx(2 * math.pi * math.sqrt(m / (2 * k)), rel=5e-3)


def test_run_releases_the_gil(block):
    """A Python thread keeps running while run() steps in C++: it ticks inside run's window."""
    sim = fsm.Simulation(block, integrator="implicit_euler")
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(time.perf_counter())

    t = threading.Thread(target=count)
    t.start()
    try:
        # One run() long enough for the thread to be scheduled many times (at least 0.05 s):
        # more steps while the machine takes less (a block at rest steps in a few us).
        steps = 3000
        while True:
            start = time.perf_counter()
            assert sim.run(steps, 1e-3) == steps
            end = time.perf_counter()
            if end - start > 0.05 or steps > 10**6:
                break
            steps *= 4
    finally:
        stop.set()
        t.join()
    margin = 0.1 * (end - start)
    inside = [x for x in ticks if start + margin < x < end - margin]
    assert end - start > 0.05
    assert len(inside) > 100


def test_drag_and_element_tangent_quality_options(block):
    """drag damps rigid motion; the element tangent choice (quality, flutter guard) changes the
    solve, not the physics."""
    model = block
    model.set_region_law(0, fsm.ForceLaw.continuum)
    results, iterations = [], []
    for quality, guard in ((0.0, True), (2.0, True), (0.3, False)):
        sim = fsm.Simulation(model, drag=5.0, element_tangent_quality=quality,
                             flutter_guard=guard)
        reports = [sim.step(1e-3) for _ in range(100)]
        assert all(r.advanced for r in reports)
        results.append(sim.model.positions.copy())
        iterations.append(sum(r.solver_iterations for r in reports))
    # The option reaches the solve (another tangent, another iteration count) but not the physics:
    # the same sag whatever the tangent (the forces are exact), to the solver's tolerance.
    assert iterations[0] != iterations[1]
    assert np.allclose(results[0], results[1], atol=1e-6)
    assert np.allclose(results[0], results[2], atol=1e-6)  # the flutter guard off: the same sag
    # The counts are the force model's: every element with quality 2.0, none fluttered when off.
    sim = fsm.Simulation(model, element_tangent_quality=2.0, flutter_guard=False)
    sim.step(1e-3)
    assert sim.element_tangents == model.num_tetrahedra
    assert sim.fluttered_elements == 0
    # The energy check's force evaluation reused by the next step: the same run to the last bit.
    runs = []
    for reuse in (True, False):
        sim = fsm.Simulation(model, reuse_end_forces=reuse)
        energies = [sim.step(1e-3).energy for _ in range(50)]
        runs.append((sim.model.positions.copy(), energies))
    assert np.array_equal(runs[0][0], runs[1][0])
    assert runs[0][1] == runs[1][1]
    # adaptive_threads: after a warm-up and 32 steps timed on the pool, steps run without it.
    sim = fsm.Simulation(model, threads=2, adaptive_threads=True)
    if sim.uses_pool:  # (one CPU: no pool)
        steps = 0
        while sim.uses_pool and steps < 3000:
            sim.step(1e-3)
            steps += 1
        assert 36 <= steps < 3000
    assert not fsm.Simulation(model).uses_pool  # one thread: no pool
    # Drag reaches the forces: in the first 5 ms of sagging the block moves slower with it.
    speed = []
    for drag in (0.0, 1000.0):
        sim = fsm.Simulation(model, drag=drag)
        assert sim.run(5, 1e-3) == 5
        speed.append(np.abs(sim.model.velocities).max())
    assert speed[1] < 0.8 * speed[0]  # 0.72 measured: drag 1000/s against the elastic response
    for bad in (dict(drag=-1.0), dict(element_tangent_quality=-0.1),
                dict(element_tangent_quality=float("nan"))):
        with pytest.raises(fsm.Error):
            fsm.Simulation(model, **bad)


def test_strain_smoothing_option(block):
    """A smoothed strain reaches the forces: the same squeeze stores less energy (softer), the
    same with any smoothing for a homogeneous strain (patch test); bad names and shares raise."""
    model = block
    model.set_region_law(0, fsm.ForceLaw.continuum)
    rest = model.rest_positions.copy()
    squeezed = rest.copy()
    squeezed[:, 2] *= 0.98  # homogeneous: every smoothing gives the element law's energy
    bent = rest.copy()
    bent[:, 2] += 0.05 * (rest[:, 0] - rest[:, 0].min()) ** 2 / np.ptp(rest[:, 0])  # not linear
    energies = {}
    for smoothing in ("element", "face", "edge", "node"):
        sim = fsm.Simulation(model, gravity=(0, 0, 0), strain_smoothing=smoothing)
        energies[smoothing] = []
        for x in (squeezed, bent):
            sim.model.positions[:] = x
            energies[smoothing].append(sim.energy().elastic)
    for smoothing in ("face", "edge", "node"):
        assert energies[smoothing][0] == pytest.approx(energies["element"][0], rel=1e-9)
        assert energies[smoothing][1] < energies["element"][1]
    for bad in (dict(strain_smoothing="nodes"), dict(smoothing_element_share=1.5)):
        with pytest.raises(fsm.Error):
            fsm.Simulation(model, **bad)
