#!/usr/bin/python3
"""What a step costs from Python: the same implicit steps taken by sim.run() (the C++ loop, one
call), by a Python loop of sim.step(), and by a Python loop that also does what a script does
every step (the probe's pose set from the positions' numpy view to keep a ball 2 mm into the
tissue, ContactSolver.step, the probe's wrench read). The difference between the first two is the binding's
cost per call (each timed block of the first two starts from rest, in alternation). Prints JSON;
docs/benchmarks.md, "From Python".

    PYTHONPATH=build/python /usr/bin/python3 bench/python_step.py MODEL.fsm [--steps N] [--repeats R]

MODEL.fsm: any model file (the bundled uterus: fsm-build data/uterus/uterus.json -o uterus.fsm).
Implicit Euler at dt = 1 ms, CG to 1e-3 (as the demo), one thread; gravity on for the first two
(the model sags from rest), off for the script's step (with the demo's drag of 5/s). Measures;
asserts nothing about time.
"""
import argparse
import json
import os
import platform
import time

import numpy as np

import fsm


def make_sim(tissue, gravity=(0.0, 0.0, -9.81), drag=0.0):
    sim = fsm.Simulation(tissue.spheres, gravity=gravity, drag=drag)
    sim.set_integrator(fsm.ImplicitEulerIntegrator(tolerance=1e-3))
    return sim


def per_step_us(run, steps, repeats):
    """The median over `repeats` of run(steps)'s wall time per step (us)."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run(steps)
        times.append((time.perf_counter() - t0) / steps * 1e6)
    return float(np.median(times)), [round(t, 2) for t in times]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    tissue = fsm.load_model(a.model)
    dt = 1e-3

    # 1 and 2: the same steps, no contacts: each timed block starts from rest (sim.reset()), so
    # both take the same steps and iterations, in alternation (the machine's drift hits both).
    sim = make_sim(tissue)

    def cpp_loop(n):
        sim.run(n, dt)

    def python_loop(n):
        step = sim.step
        for _ in range(n):
            step(dt)

    times = {cpp_loop: [], python_loop: []}
    for _ in range(a.repeats):
        for f in (cpp_loop, python_loop):
            sim.reset()
            times[f].append(per_step_us(f, a.steps, 1)[0])
    run_all, loop_all = ([round(t, 2) for t in times[f]] for f in (cpp_loop, python_loop))
    run_us, loop_us = (float(np.median(times[f])) for f in (cpp_loop, python_loop))

    # 3: a script's step: a 5 mm ball pressed 2 mm into the top of the largest part through the
    # contact solver, the probe moved to follow the tissue and its wrench read every step.
    # Gravity off here, as
    # in examples/python/build_and_probe.py (the organ supported): under gravity the tissue sags
    # away from a ball held still. The demo's drag (5/s, the surrounding tissue): without it an
    # organ held at a few nodes (the VHF pelvis's uterus) swings away from the push.
    sim = make_sim(tissue, gravity=(0.0, 0.0, 0.0), drag=5.0)
    solver = fsm.ContactSolver(sim)
    x = sim.model.positions
    part = max(tissue.parts, key=lambda p: p.num_nodes)
    top = part.first_node + int(np.argmax(x[part.nodes, 2]))
    radius = 0.005
    centre = x[top] + (0.0, 0.0, radius - 0.002)
    probe = solver.add_instrument(fsm.Instrument(fsm.SphereShape(radius), fsm.Pose(centre),
                                                 name="probe"))
    for _ in range(200):  # settle against the ball
        solver.step(sim, dt)

    pose = solver.instrument(probe).pose  # a view: the script moves the ball in place

    def script_loop(n):
        for _ in range(n):
            # keep the ball 2 mm into the tissue where it is now (an organ held at a few nodes
            # moves away from a ball held still)
            pose.position[:] = sim.model.positions[top] + (0.0, 0.0, radius - 0.002)
            solver.step(sim, dt)
            solver.wrench(probe)  # what a haptic or logging script reads every step
    script_us, script_all = per_step_us(script_loop, a.steps, a.repeats)
    contacts = int(np.sum(solver.contacts["instrument"] == probe))

    print(json.dumps({
        "model": os.path.basename(a.model), "spheres": int(sim.model.num_nodes),
        "steps": a.steps, "repeats": a.repeats, "machine": platform.processor() or platform.machine(),
        "sim_run_us": round(run_us, 2), "python_loop_us": round(loop_us, 2),
        "binding_cost_per_call_us": round(loop_us - run_us, 2),
        "script_step_us": round(script_us, 2), "probe_contacts": contacts,
        "runs_us": {"sim_run": run_all, "python_loop": loop_all, "script": script_all}}, indent=1))


if __name__ == "__main__":
    main()
