"""Sweep Young's modulus, viscosity (link damping) and sphere radius; measure the indentation
stiffness of the paper's 20 x 20 x 10 mm sample and the cost of a step.

Each point runs the flat-punch experiment of indentation.py to a shallow 0.5 mm past the 0.05 N
preload (the small-strain, linear range) and fits the initial stiffness (N/m). One parameter varies
at a time around the paper's tissue (E = 13.15 kPa, eta = 10.26 Pa s, r = 1 mm, i.e. a 2 mm
lattice). The radius sweep changes the lattice spacing (2 r), so it is the resolution sweep:
the punch needs 2 mm / spacing to be a whole number. Writes sweep.csv and sweep.png to --out.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/parameter_sweep.py --out /tmp/sweep
    ... --quick    # 2 values per parameter, coarse lattice only (test suite)

measure_point() is what dask_sweep.py runs on the workers.
"""
import argparse
import csv
import os
import sys
import time

BASE = {"youngs_modulus": 13150.0, "viscosity": 10.26, "radius": 0.001}
FULL = {"youngs_modulus": [5e3, 13150.0, 30e3, 60e3],
        "viscosity": [0.0, 10.26, 100.0, 1000.0],
        "radius": [0.001, 0.0005]}
QUICK = {"youngs_modulus": [5e3, 30e3], "viscosity": [10.26, 1000.0], "radius": [0.001]}
UNITS = {"youngs_modulus": "Pa", "viscosity": "Pa s", "radius": "m"}


def sweep_points(quick=False):
    """The points to run: the baseline, then one parameter changed at a time."""
    points = [dict(BASE, varied="baseline")]
    for name, values in (QUICK if quick else FULL).items():
        for v in values:
            if v != BASE[name]:
                points.append(dict(BASE, **{name: v}, varied=name))
    return points


def measure_point(point, depth=0.5e-3, speed=2.5e-3):
    """Runs one sweep point (a dict with youngs_modulus, viscosity, radius); returns the point
    with the fitted stiffness (N/m), the force at `depth` (N), spheres, steps and seconds per step.

    Imports fsm itself, so it runs anywhere fsm is importable (a dask worker, a subprocess).
    """
    import numpy as np

    import fsm  # noqa: F401  (indentation uses it; imported here so a worker fails early)
    here = os.path.dirname(os.path.abspath(__file__))
    if here not in sys.path:
        sys.path.insert(0, here)
    import indentation

    material = indentation.paper_tissue(point["youngs_modulus"], point["viscosity"])
    start = time.perf_counter()
    r = indentation.indent(spacing=2 * point["radius"], depth=depth, speed=speed,
                           material=material, samples=20)
    d, f = r["displacement"], r["force"]
    stiffness = float(np.polyfit(d, f, 1)[0])
    return dict(point, stiffness=stiffness, force=float(f[-1]), spheres=r["spheres"],
                steps=r["steps"], seconds_per_step=r["seconds_per_step"],
                wall=time.perf_counter() - start)


def write_outputs(results, out):
    """sweep.csv and a three-panel sweep.png (stiffness and step cost against each parameter)."""
    os.makedirs(out, exist_ok=True)
    keys = ["varied", "youngs_modulus", "viscosity", "radius", "spheres", "stiffness", "force",
            "steps", "seconds_per_step", "wall"]
    csv_path = os.path.join(out, "sweep.csv")
    with open(csv_path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(results)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    base = next(r for r in results if r["varied"] == "baseline")
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    for ax, name in zip(axes, ["youngs_modulus", "viscosity", "radius"]):
        rows = sorted([r for r in results if r["varied"] == name] + [base], key=lambda r: r[name])
        x = [r[name] for r in rows]
        ax.plot(x, [r["stiffness"] for r in rows], "o-", color="C0")
        ax.set_xlabel(f"{name} ({UNITS[name]})")
        ax.set_ylabel("indentation stiffness (N/m)", color="C0")
        ax.grid(alpha=0.3)
        cost = ax.twinx()
        cost.plot(x, [r["seconds_per_step"] * 1e3 for r in rows], "s--", color="C1")
        cost.set_ylabel("ms per step", color="C1")
    fig.suptitle("Flat-punch stiffness (0-0.5 mm) and step cost, 20 x 20 x 10 mm sample")
    fig.tight_layout()
    png_path = os.path.join(out, "sweep.png")
    fig.savefig(png_path, dpi=110)
    return csv_path, png_path


def print_table(results):
    print(f"{'varied':>15} {'E (kPa)':>8} {'eta (Pa s)':>10} {'r (mm)':>7} {'spheres':>8} "
          f"{'k (N/m)':>8} {'F (N)':>7} {'us/step':>8}")
    for r in results:
        print(f"{r['varied']:>15} {r['youngs_modulus'] / 1e3:8.2f} {r['viscosity']:10.2f} "
              f"{r['radius'] * 1e3:7.2f} {r['spheres']:8d} {r['stiffness']:8.1f} "
              f"{r['force']:7.3f} {r['seconds_per_step'] * 1e6:8.0f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="sweep-out", help="output folder")
    ap.add_argument("--quick", action="store_true", help="a small sweep (test suite)")
    args = ap.parse_args()
    start = time.perf_counter()
    results = [measure_point(p) for p in sweep_points(args.quick)]
    print_table(results)
    csv_path, png_path = write_outputs(results, args.out)
    print(f"{len(results)} points in {time.perf_counter() - start:.1f} s; wrote {csv_path} and "
          f"{png_path}")


if __name__ == "__main__":
    main()
