#!/usr/bin/python3
"""Flat-ended tools and the ball on the cylindrical specimen filled with spheres graded toward
the tool, against the converged axisymmetric reference (docs/validation.md, "Spheres fine where
the tool works").

    /usr/bin/python3 validation/graded_tools.py --indent build/validation/fsm-indent \
        [--work /tmp/graded_tools] [--sizes 0.8 0.7 0.6 0.5 0.45 0.4] [--reuse]

The specimen of continuum_sweep.py's disc studies (radius 10 mm, height 10 mm, bonded bottom) is
filled under the scene's graded metric: size_min h_0 within RADIUS (4 mm: the tools' 3 mm radius
and 1 mm more) of the top's centre, growing linearly to SIZE_MAX (2.5 mm) over DISTANCE (4 mm).
One mesh per h_0 serves every tool; fsm-indent presses each tool into its centre at 150 mm/min
with the default contact (sphere centres, ContactOptions defaults), E = 13.15 kPa and nu as
given, no factor, as in continuum_sweep.py. Each run is scored by continuum_sweep.score: the
largest relative force error from 0.5 to 2.5 mm (the issue's 5 % target) and from 1.25 to 2.5 mm
(where the sharp rim's reference is good to 2 %: at 0.5-1 mm its own uncertainty is up to 15 %),
the force at 1.25 mm against the reference's, the largest displacement difference at equal force.

Also four neighbours of the h_0 = 0.5 mm filling (VARIANTS: another plateau radius, distance or
bulk size), with the continuum law: how much the result depends on that choice.

Writes validation/results/graded_tools.json ("runs": the family; "variants") and
docs/img/validation_graded_tools.png (the largest force error against the sphere count, graded
against the uniform fillings of results/continuum_sweep.json).
"""
import argparse
import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import continuum_sweep  # noqa: E402
import scenes  # noqa: E402
import validate  # noqa: E402

RADIUS, DISTANCE, SIZE_MAX = 4.0, 4.0, 2.5  # mm: the family's plateau, growth and bulk size
# Neighbours of the family's h_0 = 0.5 mm filling (h_0, plateau radius, distance, size_max in mm),
# run with the continuum law only: how much the result depends on the plateau and the bulk.
VARIANTS = [(0.5, 3.5, 4.0, 2.5), (0.5, 4.5, 3.0, 2.5), (0.5, 4.0, 4.0, 2.0), (0.5, 4.0, 3.0, 2.0)]
# (case, nu): the tools with a converged reference (the sharp rim has none at nu = 0.49).
STUDIES = [("disc_rounded_cylinder", 0.49), ("disc_rounded_cylinder", 0.45),
           ("disc_cylinder", 0.45), ("disc_sphere", 0.49), ("disc_sphere", 0.45)]
LAWS = ("continuum", "links")  # the paper's link network beside the continuum law


def tag_of(h0, radius=RADIUS, distance=DISTANCE, size_max=SIZE_MAX):
    """A filling's name: every parameter of its metric (so --reuse never takes another's run)."""
    return f"h{h0:g}_r{radius:g}_d{distance:g}_max{size_max:g}"


def graded_scene(work, disc, h0, radius=RADIUS, distance=DISTANCE, size_max=SIZE_MAX):
    """The specimen's scene, h0 (mm) within `radius` of the top's centre, growing to size_max over
    `distance`."""
    path = os.path.join(work, f"graded_{tag_of(h0, radius, distance, size_max)}.json")
    scenes.write_scene(path, disc, "tetrahedral", size_max, scenes.LINEAR,
                       graded=(h0, distance, radius))
    return path


def run(a, scene, filling, case, law, nu):
    """One fsm-indent run (reused with --reuse): (curve path, its JSON summary)."""
    return continuum_sweep.indent_tagged(
        a, scene, case, law, nu, f"{filling}_{case}_{law}" + (f"_nu{nu:g}" if law != "links" else ""))


def chart(rows, uniform):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = {"disc_rounded_cylinder": "rounded rim", "disc_cylinder": "sharp rim",
             "disc_sphere": "ball"}
    fig, grid = plt.subplots(2, 3, figsize=(12, 7.5), sharey=True)
    axes = grid.ravel()
    axes[-1].axis("off")
    for ax, (case, nu) in zip(axes, STUDIES):
        for src, law, key, style, label in (
                (uniform, "continuum", "max_rel_force_error_0p5_2p5", "o--", "continuum law, uniform"),
                (rows, "continuum", "max_rel_force_error_0p5_2p5", "s-",
                 "continuum law, graded toward the tool"),
                (rows, "continuum", "max_rel_force_error_1p25_2p5", "s:",
                 "graded, past 1.25 mm only (the sharp rim's reference\nis uncertain by 15 % at 0.5 mm, 10 % at 1 mm)"),
                (rows, "links", "max_rel_force_error_0p5_2p5", "^:", "paper's link network, graded")):
            if key.endswith("1p25_2p5") and case != "disc_cylinder":
                continue
            pts = sorted((x["spheres"], 100 * x[key]) for x in src
                         if x["case"] == case and x["nu"] == nu and x["law"] == law)
            if pts:
                ax.plot(*zip(*pts), style, label=label, color="0.55" if law == "links" else None,
                        mfc="none" if key.endswith("1p25_2p5") else None)
        ax.axhline(5, color="k", lw=0.8, ls=":")
        ax.axvline(2000, color="0.6", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylim(0.8, 100)
        ax.set_title(f"{names[case]}, nu = {nu:g}")
        ax.set_xlabel("spheres")
    for ax in grid[:, 0]:
        ax.set_ylabel("largest force error, 0.5-2.5 mm (%)")
    handles = {}
    for ax in axes[:-1]:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    axes[-1].legend(handles.values(), handles.keys(), loc="center", fontsize=8)
    fig.suptitle("Cylindrical specimen, continuum law, vertex contact: uniform fillings and fillings "
                 "graded toward the tool\n(dotted: the 5 % target and 2,000 spheres)", fontsize=10)
    fig.tight_layout()
    out = os.path.join(ROOT, "docs", "img", "validation_graded_tools.png")
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--indent", required=True)
    ap.add_argument("--work", default="/tmp/graded_tools")
    ap.add_argument("--sizes", type=float, nargs="+", default=[0.8, 0.7, 0.6, 0.5, 0.45, 0.4],
                    help="h_0 (mm) of each filling")
    ap.add_argument("--reuse", action="store_true", help="keep runs already in --work")
    ap.add_argument("--charts-only", action="store_true",
                    help="redraw the chart from results/graded_tools.json")
    a = ap.parse_args()
    result = os.path.join(HERE, "results", "graded_tools.json")
    with open(os.path.join(HERE, "results", "continuum_sweep.json")) as f:
        uniform = [x for x in json.load(f)["runs"]
                   if x["case"].startswith("disc_") and "failed" not in x]
    if a.charts_only:
        with open(result) as f:
            chart(json.load(f)["runs"], uniform)
        return
    os.makedirs(a.work, exist_ok=True)
    disc = os.path.join(a.work, "disc.off")
    scenes.write_disc_off(disc)
    rows, variants = [], []
    fillings = [((h0, RADIUS, DISTANCE, SIZE_MAX), LAWS, rows) for h0 in a.sizes]
    fillings += [(v, ("continuum",), variants) for v in VARIANTS]
    for (h0, radius, distance, size_max), laws, out in fillings:
        scene = graded_scene(a.work, disc, h0, radius, distance, size_max)
        filling = tag_of(h0, radius, distance, size_max)
        links = {}  # the link network has no Poisson's ratio: one run per tool, scored at each nu
        for case, nu in STUDIES:
            for law in laws:
                if law == "links":
                    if case not in links:
                        links[case] = run(a, scene, filling, case, law, nu)
                    curve, s = links[case]
                else:
                    curve, s = run(a, scene, filling, case, law, nu)
                d, F = validate.read_curve(curve)
                row = {"size_min_mm": h0, "plateau_radius_mm": radius, "distance_mm": distance,
                       "size_max_mm": size_max, "case": case, "nu": nu, "law": law,
                       "spheres": s["spheres"], "tetrahedra": s.get("tetrahedra"),
                       **continuum_sweep.score(d, F, case, nu),
                       # Past 1.25 mm only: where the sharp rim's reference is good to 2 % (it is
                       # uncertain by up to 15 % at 0.5-1 mm: converged_disc_cylinder_nu0.45.csv).
                       "max_rel_force_error_1p25_2p5": validate.max_force_error(
                           d, F, *validate.converged_reference(case, nu), lo=1.25, hi=2.5),
                       "median_step_us": s["median_step_us"], "mean_iterations": s["mean_iterations"],
                       "diverged": s["diverged"], "inverted_steps": s["inverted_steps"],
                       "max_penetration_m": s["max_penetration_m"],
                       "max_face_penetration_m": s.get("max_face_penetration_m"), "curve": curve}
                out.append(row)
                print(json.dumps(row), flush=True)
    with open(result, "w") as f:
        json.dump({"command": "validation/graded_tools.py " + " ".join(sys.argv[1:]),
                   "date": time.strftime("%Y-%m-%d"), "runs": rows, "variants": variants}, f,
                  indent=1)
    chart(rows, uniform)


if __name__ == "__main__":
    main()
