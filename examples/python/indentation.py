"""The paper's indentation experiment on a virtual tissue sample (docs/physics.md section 10.6).

A 20 x 20 x 10 mm block of the paper's bilinear tissue (13.15 / 68.38 kPa, 10.26 Pa s) is filled
with spheres as in examples/poke_block.cpp, its bottom is clamped, and a rigid 4 x 4 mm flat punch
is driven into the middle of its top at 5 mm/min to 2.5 mm. The punch is displacement-controlled:
the top spheres under it are held (fixed) and moved with it, like tissue stuck to a rigid face, and
the punch force is the sum of the forces the tissue exerts on those spheres. As in the
experiment, displacement is zeroed at a 0.05 N preload. Runs both force laws, the paper's link
network and the continuum law (neo-Hookean tetrahedra, Poisson's ratio --nu), with E as given (no
fitted factor), and writes their force-displacement curves to indentation.csv and indentation.png
in --out. The link network softens, its force falls and tetrahedra under the punch invert; the
continuum law rises monotonically to 2.5 mm.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/indentation.py --out /tmp/indent
    ... --quick    # 1 s of loading instead of 30: a few seconds, for the test suite
"""
import argparse
import csv
import os
import time

import numpy as np

import fsm

WIDTH, HEIGHT, PUNCH = 0.020, 0.010, 0.004  # m
PRELOAD = 0.05  # N: where the experiment zeroes the displacement


def paper_tissue(youngs_modulus=13150.0, viscosity=10.26):
    """The paper's bilinear tissue; the switch strain (10 %) is ours, the paper does not give it."""
    return fsm.Material(density=1050.0, youngs_modulus=youngs_modulus, viscosity=viscosity,
                        large_strain_modulus=youngs_modulus * 68380.0 / 13150.0, switch_strain=0.10)


def make_block(spacing=0.002, material=None, radius_factor=0.5):
    """The 20 x 20 x 10 mm sample as a Freudenthal lattice of `spacing` (m) with its bottom fixed.

    Returns (model, punch_nodes, tetrahedra): the SphereModel, the indices of the top spheres under
    the 4 x 4 mm punch and the lattice's tetrahedra (node indices). Sphere radius is
    radius_factor * spacing.
    """
    material = material or paper_tissue()
    cells = (round(WIDTH / spacing), round(WIDTH / spacing), round(HEIGHT / spacing))
    h = WIDTH / cells[0]
    model = fsm.SphereModel()
    region = model.add_region("sample", material)
    lattice = fsm.make_cube_lattice((0, 0, 0), cells, h)
    fsm.add_tetrahedral_part(model, lattice, region, radius_factor * h)  # node k = vertex k
    x = model.rest_positions
    for i in np.flatnonzero(x[:, 2] < 1e-9):
        model.set_fixed(int(i))
    eps = 1e-9
    under = ((x[:, 2] > cells[2] * h - eps) & (np.abs(x[:, 0] - WIDTH / 2) <= PUNCH / 2 + eps)
             & (np.abs(x[:, 1] - WIDTH / 2) <= PUNCH / 2 + eps))
    return model, np.flatnonzero(under), lattice.tetrahedra


def signed_volumes(x, tetrahedra):
    """Signed volume (m^3) of each tetrahedron at positions x."""
    a, b, c, d = (x[tetrahedra[:, k]] for k in range(4))
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6


def indent(spacing=0.002, depth=0.0025, speed=5e-3 / 60, dt=1e-3, material=None,
           radius_factor=0.5, samples=60, integrator="implicit_euler", law="links", nu=0.45):
    """Drives the punch `depth` (m) past the preload point at `speed` (m/s).

    Returns a dict: displacement (m) and force (N) arrays sampled during loading (displacement
    zeroed at the preload), the block's size, the number of steps and the mean seconds per step.
    """
    material = material or paper_tissue()
    if law == "continuum":
        material = fsm.Material(density=material.density, youngs_modulus=material.youngs_modulus,
                                viscosity=material.viscosity,
                                large_strain_modulus=material.large_strain_modulus,
                                switch_strain=material.switch_strain, poisson_ratio=nu)
    model, held, tets = make_block(spacing, material, radius_factor)
    if law == "continuum":
        model.set_region_law(0, fsm.ForceLaw.continuum)
    # The punch moves held spheres by editing their positions, which does work the energy check
    # cannot see: it is turned off (the implicit scheme is unconditionally stable anyway).
    sim = fsm.Simulation(model, integrator=integrator, check_energy=False)
    for i in held:
        sim.set_fixed(int(i))
    rest_z = sim.model.rest_positions[held, 2].copy()
    travel, zero = 0.0, None
    disp, force = [], []
    steps, busy = 0, 0.0
    sample_every = depth / samples
    next_sample = 0.0
    while zero is None or travel - zero < depth + 1e-12:
        travel += speed * dt
        sim.model.positions[held, 2] = rest_z - travel
        t0 = time.perf_counter()
        report = sim.step(dt)
        busy += time.perf_counter() - t0
        steps += 1
        if not report.advanced:
            raise RuntimeError(f"step {steps} failed: {report.status}")
        if zero is None and travel > HEIGHT / 2:
            raise RuntimeError(f"no {PRELOAD} N preload after {travel * 1e3:.1f} mm of travel")
        if zero is None or travel - zero >= min(next_sample, depth - 1e-12):
            f = sim.internal_forces()[held, 2].sum()  # the tissue pushes the punch up: +
            if zero is None and f >= PRELOAD:
                zero = travel
            if zero is not None:
                disp.append(travel - zero)
                force.append(f)
                next_sample = travel - zero + sample_every
    return {"displacement": np.array(disp), "force": np.array(force), "spheres": model.num_nodes,
            "links": model.num_links, "held": len(held), "steps": steps,
            "seconds_per_step": busy / steps, "preload_travel": zero,
            "inverted": int(np.sum(signed_volumes(sim.model.positions, tets)
                                   * signed_volumes(sim.model.rest_positions, tets) < 0))}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="indentation-out", help="output folder")
    ap.add_argument("--quick", action="store_true", help="fast loading (for the test suite)")
    ap.add_argument("--spacing", type=float, default=0.002,
                    help="lattice spacing (m); 2 mm / spacing should be a whole number")
    ap.add_argument("--speed", type=float, default=5e-3 / 60, help="punch speed (m/s)")
    ap.add_argument("--dt", type=float, default=1e-3, help="time step (s)")
    ap.add_argument("--nu", type=float, default=0.45, help="Poisson's ratio of the continuum law")
    args = ap.parse_args()
    if args.quick:
        args.speed = 2.5e-3  # 1 s of loading instead of 30 (quasi-static all the same)
    os.makedirs(args.out, exist_ok=True)

    results = {}
    for law in ("links", "continuum"):
        start = time.perf_counter()
        r = indent(spacing=args.spacing, speed=args.speed, dt=args.dt, law=law, nu=args.nu)
        r["wall"] = time.perf_counter() - start
        results[law] = r
        d, f = r["displacement"], r["force"]
        print(f"[{law}] libfsm {fsm.__version__}: block 20 x 20 x 10 mm, {r['spheres']} spheres; "
              f"punch 4 x 4 mm holds {r['held']} spheres")
        print(f"[{law}] preload {PRELOAD} N after {r['preload_travel'] * 1e3:.3f} mm; loaded to "
              f"{d[-1] * 1e3:.2f} mm at {args.speed * 6e4:.1f} mm/min, dt {args.dt * 1e3:g} ms")
        print(f"{'d (mm)':>8} {'F (N)':>8}")
        for k in np.linspace(0, len(d) - 1, 11).astype(int):
            print(f"{d[k] * 1e3:8.3f} {f[k]:8.4f}")
        monotonic = bool(np.all(np.diff(f) >= -1e-9))
        print(f"[{law}] force at {d[-1] * 1e3:.2f} mm: {f[-1]:.3f} N; rises monotonically: "
              f"{monotonic}; inverted tetrahedra at the end: {r['inverted']}")
        peak = int(np.argmax(f))
        if f[peak:].min() < 0.8 * f[peak]:
            print(f"[{law}] note: the force falls after {d[peak] * 1e3:.2f} mm ({f[peak]:.3f} N): a "
                  "central-spring network has no bulk stiffness to resist the tetrahedra under "
                  "the punch inverting (the continuum law does).")
        print(f"[{law}] {r['steps']} steps, {r['seconds_per_step'] * 1e6:.0f} us per step; "
              f"wall {r['wall']:.1f} s")

    csv_path = os.path.join(args.out, "indentation.csv")
    with open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["law", "displacement_mm", "force_N"])
        for law, r in results.items():
            w.writerows((law, a, b) for a, b in zip(np.round(r["displacement"] * 1e3, 6),
                                                    np.round(r["force"], 6)))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 4))
    for law, r in results.items():
        label = (f"link network, paper ({r['spheres']} spheres)" if law == "links"
                 else f"continuum law, nu = {args.nu:g}")
        ax.plot(r["displacement"] * 1e3, r["force"], "-", label=label)
    ax.set_xlabel("displacement (mm)")
    ax.set_ylabel("force (N)")
    ax.set_title("Flat-punch indentation, 20 x 20 x 10 mm sample")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    png_path = os.path.join(args.out, "indentation.png")
    fig.savefig(png_path, dpi=120)
    print(f"wrote {csv_path} and {png_path}")


if __name__ == "__main__":
    main()
