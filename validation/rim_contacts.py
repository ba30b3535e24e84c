#!/usr/bin/env python3
"""Where the vertex contact's spheres sit under a flat-ended tool (docs/validation.md, "Flat-ended
tools against a converged reference"): the cylindrical specimen of a scene written by
continuum_sweep.py (disc_r<R>.json in its --work folder), continuum law, the tool pressed 2.5 mm at
150 mm/min as fsm-indent does, through the Python bindings. Every 0.25 mm of depth it prints the
tool's force and the sphere centres in contact binned by their distance from the tool's axis (the
flat end of the rounded tool reaches 2 mm, its 1 mm rim 2-3 mm, the side wall 3 mm). How deep the
faces between them cut into the tool, fsm-indent reports (`max_face_penetration_m`).

    PYTHONPATH=build/python /usr/bin/python3 validation/rim_contacts.py /tmp/sweep/disc_r1.25.json
"""
import argparse

import numpy as np

import fsm
import fsm.build

BINS_MM = [0, 1, 2, 2.25, 2.5, 2.75, 2.95, 3.01]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", help="a disc scene of continuum_sweep.py (disc_r<R>.json)")
    ap.add_argument("--nu", type=float, default=0.49)
    ap.add_argument("--edge-radius", type=float, default=1.0, help="the rim's radius (mm); 0 = sharp")
    a = ap.parse_args()

    tissue, _, _ = fsm.build.build_model(a.scene)
    m = tissue.spheres
    mat = m.regions[0].material
    mat.poisson_ratio = a.nu
    m.set_region_material(0, mat)
    m.set_region_law(0, fsm.ForceLaw.continuum)
    rest = np.array(m.rest_positions)
    zmin, zmax = rest[:, 2].min(), rest[:, 2].max()
    cx = 0.5 * (rest[:, 0].min() + rest[:, 0].max())
    cy = 0.5 * (rest[:, 1].min() + rest[:, 1].max())
    for i in range(m.num_nodes):  # the lowest layer held, as fsm-indent does
        m.set_fixed(i, bool(rest[i, 2] <= zmin + 1e-6))
    sim = fsm.Simulation(m, gravity=(0, 0, 0))
    solver = fsm.ContactSolver(sim)
    radius, half, rim = 3e-3, 5e-3, a.edge_radius * 1e-3
    start_z, speed, dt = zmax + half, 2.5e-3, 1e-3
    tool = solver.add_instrument(fsm.Instrument(fsm.CylinderShape(radius, half, rim),
                                                fsm.Pose((cx, cy, start_z)), friction=0.0))
    print("depth_mm force_N contacts contacts_by_distance_from_axis_mm "
          + " ".join(f"[{lo:g},{hi:g})" for lo, hi in zip(BINS_MM, BINS_MM[1:])))
    for s in range(1, 1001):
        ins = solver.instrument(tool)
        ins.pose.position[2] = start_z - speed * (s - 1) * dt
        ins.linear_velocity[:] = (0, 0, -speed)
        solver.step(sim, dt)
        ins.pose.position[2] = start_z - speed * s * dt
        if s % 100:
            continue
        x = np.array(sim.model.positions)
        idx = solver.contacts["sphere"]
        rho = np.hypot(x[idx, 0] - cx, x[idx, 1] - cy) * 1e3
        hist = np.histogram(rho, bins=BINS_MM)[0]
        print(f"{speed * s * dt * 1e3:.2f} {solver.wrench(tool).force[2]:.4f} {len(idx)} "
              + " ".join(map(str, hist)), flush=True)


if __name__ == "__main__":
    main()
