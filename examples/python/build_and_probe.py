"""Build the default uterus, simulate it, and press a ball probe into the fundus.

The scene data/uterus/uterus.json is built with fsm.build (the GPL builder module), simulated with
fsm.Simulation, and a 5 mm ball instrument is pushed into the top of the uterine body through an
fsm.ContactSolver, one depth at a time, holding each depth until the tissue settles. The table
printed is the probe force (what a haptic device would render) against depth; probe.csv and
probe.png go to --out.

Gravity is off by default (the organ lies supported in the abdomen, and the probe's force is the
only load); --gravity turns it on, and the model then first settles under its own weight.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/build_and_probe.py --out /tmp/probe
    ... --quick    # fewer, shorter holds, for the test suite
"""
import argparse
import csv
import os
import time

import numpy as np

import fsm
import fsm.build

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "..", "..", "data", "uterus", "uterus.json")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="probe-out", help="output folder")
    ap.add_argument("--quick", action="store_true", help="fewer and shorter holds (test suite)")
    ap.add_argument("--scene", default=SCENE, help="scene file to build")
    ap.add_argument("--probe-radius", type=float, default=0.005, help="ball probe radius (m)")
    ap.add_argument("--max-depth", type=float, default=0.006, help="deepest press (m)")
    ap.add_argument("--hold", type=float, default=0.1, help="seconds held at each depth")
    ap.add_argument("--dt", type=float, default=1e-3, help="time step (s)")
    ap.add_argument("--gravity", action="store_true", help="gravity on (settle first)")
    args = ap.parse_args()
    depths = np.linspace(0, args.max_depth, 4 if args.quick else 13)
    hold_steps = max(1, round((0.03 if args.quick else args.hold) / args.dt))
    os.makedirs(args.out, exist_ok=True)

    t0 = time.perf_counter()
    tissue, report, table = fsm.build.build_model(args.scene)
    build_s = time.perf_counter() - t0
    print(table)
    print(f"built {tissue} in {build_s:.1f} s")

    sim = fsm.Simulation(tissue.spheres, gravity=(0, 0, -9.81) if args.gravity else (0, 0, 0))
    # The contact solver hands its contacts to the simulation's force model each step, and implicit
    # Euler takes their stiffness into its solve (solver.step = compute, sim.step, collect).
    solver = fsm.ContactSolver(sim)

    def step():
        return solver.step(sim, args.dt)

    if args.gravity:  # settle under gravity before probing
        for _ in range(round((0.2 if args.quick else 1.0) / args.dt)):
            step()

    # Touch the top of the uterine body from above.
    body = tissue.part("body")
    x = sim.model.positions.copy()  # a copy: sim.model.positions is a live view
    top = body.first_node + int(np.argmax(x[body.nodes, 2]))
    # The body is a tetrahedral filling: its vertices are its surface and meet instruments at
    # their centres (ContactOptions.tetrahedral_surface).
    touch = x[top] + (0.0, 0.0, args.probe_radius)
    probe = solver.add_instrument(fsm.Instrument(fsm.SphereShape(args.probe_radius),
                                                 fsm.Pose(touch), name="probe", friction=0.2))
    print(f"probe: ball of {args.probe_radius * 1e3:g} mm over sphere {top} at "
          f"{np.round(touch * 1e3, 1)} mm; {sim.model.num_nodes} spheres, "
          f"{'gravity on' if args.gravity else 'no gravity'}")

    rows = []
    print(f"\n{'depth (mm)':>10} {'Fz (N)':>9} {'|F| (N)':>9} {'contacts':>9} "
          f"{'top moved (mm)':>15} {'step (ms)':>10}")
    for depth in depths:
        pose = solver.instrument(probe).pose
        pose.position[:] = touch - (0.0, 0.0, depth)
        t0 = time.perf_counter()
        for _ in range(hold_steps):
            report = step()
        per_step = (time.perf_counter() - t0) / hold_steps
        w = solver.wrench(probe)
        c = solver.contacts
        n_probe = int(np.sum(c["instrument"] == probe))
        moved = float(np.linalg.norm(sim.model.positions[top] - x[top])) if depth else 0.0
        rows.append((depth, w.force[2], np.linalg.norm(w.force), n_probe, moved, per_step))
        print(f"{depth * 1e3:10.2f} {w.force[2]:9.4f} {np.linalg.norm(w.force):9.4f} "
              f"{n_probe:9d} {moved * 1e3:15.3f} {per_step * 1e3:10.2f}   {report.status}")

    csv_path = os.path.join(args.out, "probe.csv")
    with open(csv_path, "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(["depth_mm", "force_z_N", "force_N", "probe_contacts", "top_moved_mm",
                     "step_ms"])
        for d, fz, f, n, mv, s in rows:
            wr.writerow([f"{d * 1e3:.4f}", f"{fz:.6f}", f"{f:.6f}", n, f"{mv * 1e3:.4f}",
                         f"{s * 1e3:.3f}"])
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = np.array([r[0] for r in rows]) * 1e3
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.plot(d, [r[1] for r in rows], "o-", label="Fz on probe")
    ax.plot(d, [r[2] for r in rows], "s--", label="|F| on probe")
    ax.set_xlabel("probe depth past first touch (mm)")
    ax.set_ylabel("force (N)")
    ax.set_title(f"Ball probe ({args.probe_radius * 1e3:g} mm) on the uterine fundus")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    png_path = os.path.join(args.out, "probe.png")
    fig.savefig(png_path, dpi=120)
    print(f"\nwrote {csv_path} and {png_path}")


if __name__ == "__main__":
    main()
