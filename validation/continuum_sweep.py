#!/usr/bin/python3
"""Both force laws, uncalibrated, against the converged CalculiX reference, at several resolutions.

    /usr/bin/python3 validation/continuum_sweep.py --indent build/validation/fsm-indent \
        [--radii 2.5 2 1.5 1.25] [--work /tmp/sweep]

For each sphere radius (the builder's isotropic metric on the 20 x 20 x 10 mm box, sharp edges
protected), each case (bonded compression, rigid 5 mm ball through contact) and each law (the
paper's link network; the continuum law at nu = 0.49), runs fsm-indent at 150 mm/min and compares
with reference/converged_<case>_nu0.49.csv: the largest displacement difference at equal force (the
paper's metric), the RMS force error, and the largest relative force error from 0.5 to 2.5 mm.
Writes validation/results/continuum_sweep.json and two charts in docs/img: error against spacing
(log-log, with the observed order) and median step time against error.
"""
import argparse
import json
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import scenes  # noqa: E402
import validate  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--indent", required=True)
    ap.add_argument("--radii", type=float, nargs="+", default=[2.5, 2.0, 1.5, 1.25])
    ap.add_argument("--work", default="/tmp/fsm-continuum-sweep")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    box = os.path.join(a.work, "box.off")
    scenes.write_box_off(box)
    rows = []
    for r in a.radii:
        scene = os.path.join(a.work, f"r{r:g}.json")
        scenes.write_scene(scene, box, "tetrahedral", r, scenes.LINEAR)
        for case in ("compression", "sphere"):
            for law in ("links", "continuum"):
                out = os.path.join(a.work, f"{case}_{law}_r{r:g}.csv")
                p = subprocess.run([a.indent, scene, "--case", case, "--law", law, "--nu", "0.49",
                                    "--speed", "150", "--out", out], capture_output=True, text=True)
                if p.returncode not in (0, 3):
                    sys.exit(f"fsm-indent failed: {p.stderr}")
                s = json.loads(p.stdout)
                d, F = validate.read_curve(out)
                dr, Fr = validate.converged_reference(case)
                m = validate.metrics(d, F, dr, Fr)
                mask = (d >= 0.5 - 1e-9) & (d <= 2.5 + 1e-9)
                rel = np.max(np.abs(F[mask] - np.interp(d[mask], dr, Fr)) / np.interp(d[mask], dr, Fr))
                row = {"radius_mm": r, "case": case, "law": law, "spheres": s["spheres"],
                       "max_disp_diff_mm": m["max_disp_diff_mm"], "rms_force_N": m["rms_force_N"],
                       "max_rel_force_error_0p5_2p5": float(rel), "force_2p5_N": float(F[-1]),
                       "reference_2p5_N": float(Fr[-1]), "median_step_us": s["median_step_us"],
                       "mean_iterations": s["mean_iterations"], "diverged": s["diverged"],
                       "inverted_steps": s["inverted_steps"],
                       "max_penetration_m": s["max_penetration_m"]}
                rows.append(row)
                print(json.dumps(row), flush=True)
    with open(os.path.join(HERE, "results", "continuum_sweep.json"), "w") as f:
        json.dump({"command": "validation/continuum_sweep.py --radii " +
                   " ".join(f"{r:g}" for r in a.radii), "runs": rows}, f, indent=1)

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    img = os.path.join(ROOT, "docs", "img")
    fig, axes = plt.subplots(1, 2, figsize=(9.5, 3.8))
    for ax, case in zip(axes, ("compression", "sphere")):
        for law, style in (("links", "o--"), ("continuum", "s-")):
            pts = [x for x in rows if x["case"] == case and x["law"] == law]
            h = np.array([x["radius_mm"] for x in pts])
            e = np.array([max(x["max_disp_diff_mm"], 1e-4) for x in pts])
            label = "paper's link network" if law == "links" else "continuum law"
            if len(h) >= 2:
                order = np.polyfit(np.log(h), np.log(e), 1)[0]
                label += f" (order {order:.2f})"
            ax.loglog(h, e, style, label=label)
        ax.axhline(0.05, color="grey", lw=0.8, ls=":", label="target 0.05 mm")
        ax.set_title(f"{case}: error against the converged reference")
        ax.set_xlabel("sphere radius (mm)")
        ax.set_ylabel("largest displacement difference (mm)")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(img, "validation_error_vs_spacing.png"), dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(5.5, 4))
    for case, marker in (("compression", "o"), ("sphere", "s")):
        for law, colour in (("links", "tab:blue"), ("continuum", "tab:red")):
            pts = [x for x in rows if x["case"] == case and x["law"] == law]
            ax.loglog([x["median_step_us"] for x in pts], [x["max_disp_diff_mm"] for x in pts],
                      marker=marker, color=colour, ls="-", label=f"{case}, {law}")
    ax.axhline(0.05, color="grey", lw=0.8, ls=":")
    ax.axvline(1000, color="grey", lw=0.8, ls=":")
    ax.set_xlabel("median implicit step, 1 ms (us, one core)")
    ax.set_ylabel("largest displacement difference (mm)")
    ax.set_title("speed against accuracy, uncalibrated")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(img, "validation_speed_accuracy_laws.png"), dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
