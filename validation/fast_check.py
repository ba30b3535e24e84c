#!/usr/bin/python3
"""Fast validation check (ctest `validation_indentation_coarse`, label `validation`).

Builds the coarse block (tetrahedral filling with sharp edges protected, r = 2 mm, ~570 spheres)
and runs, with the continuum law at nu = 0.49 and E as given (no fitted factor), the bonded
compression and the rigid 5 mm ball pressed through contact, at 150 mm/min (quasi-static). Each is
compared with the converged CalculiX reference (reference/converged_<case>_nu0.49.csv,
Richardson-extrapolated). It fails if the largest displacement difference at equal force exceeds
the figure stored in reference/fast_check.json (measured when the check was written) by more than
0.05 mm, or if any step diverged or an element inverted. As a negative control it runs the
compression with the paper's link network (2.5x too soft) and fails unless the tolerance rejects
it, so the check cannot silently lose its teeth. It also runs the compression with node-smoothed
strains (ForceModel::Options::strain_smoothing), whose stored figure is far below the element
law's: the check fails if the option stops reaching the forces. And it presses the rigid cylinder
with a rounded rim (no converged reference: docs/validation.md) to 2.5 mm and fails if any sphere
centre ended more than MAX_PENETRATION_M inside it or a step diverged; before the near contacts
(ContactOptions::detection_margin) spheres under the rim sank 22 um on this block (0.3 mm at
1.25 mm spacing). Last, it presses the same rounded cylinder into the cylindrical specimen
(validation/axisym.py), where it has a converged reference, and fails if the largest force error
from 0.5 to 2.5 mm exceeds the stored figure by more than 5 points (or a sphere centre sank, a step
diverged or an element inverted); and into the same specimen filled with spheres graded toward the
tool (h_0 = 0.5 mm within 4 mm of the top's centre, 1,431 spheres: graded_tools.py), where that
error is 4.2 %, within the issue's 5 % target: it fails past 5.2 % (1 point more), or on the same
events.
"""
import argparse
import json
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
MAX_PENETRATION_M = 5e-6  # the ball's and the rounded cylinder's, at r = 2 mm: 1-2 um
sys.path.insert(0, HERE)
import graded_tools  # noqa: E402
import scenes  # noqa: E402
import validate  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--indent", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    stored = json.load(open(os.path.join(HERE, "reference", "fast_check.json")))
    box = os.path.join(a.work, "box.off")
    scenes.write_box_off(box)
    scene = os.path.join(a.work, "coarse.json")
    scenes.write_scene(scene, box, "tetrahedral", stored["radius_mm"], scenes.LINEAR)

    def run(case, law, smoothing="element"):
        out = os.path.join(a.work, f"{case}_{law}_{smoothing}.csv")
        r = subprocess.run([a.indent, scene, "--case", case, "--speed", "150", "--law", law,
                            "--nu", "0.49", "--smoothing", smoothing, "--out", out],
                           capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"fsm-indent failed ({r.returncode}): {r.stderr}")
        summary = json.loads(r.stdout)
        d, F = validate.read_curve(out)
        dr, Fr = validate.converged_reference(case)
        return validate.metrics(d, F, dr, Fr), summary

    failures = []
    # The sweep's force error interpolates the reference as a power law between its samples
    # (validate.interp_power): exact on a Hertz-like curve where a chord is not.
    dr = np.linspace(0, 2.5, 11)
    x = np.linspace(0.05, 2.5, 99)
    power_err = np.max(np.abs(validate.interp_power(x, dr, dr ** 1.5) / x ** 1.5 - 1))
    chord_err = np.max(np.abs(np.interp(x[x >= 0.5], dr, dr ** 1.5) / x[x >= 0.5] ** 1.5 - 1))
    print(f"reference interpolation on F = d^1.5 sampled every 0.25 mm: power law "
          f"{power_err:.1e}, chord {100 * chord_err:.1f} % from 0.5 mm")
    if not (power_err < 1e-9 and chord_err > 0.01):
        failures.append("validate.interp_power is not exact on a power law")
    for key, case, smoothing in (("compression", "compression", "element"),
                                 ("sphere", "sphere", "element"),
                                 ("compression_node", "compression", "node")):
        want = stored[key]["max_disp_diff_mm"]
        limit = want + 0.05
        m, s = run(case, "continuum", smoothing)
        print(f"{case} (continuum, {smoothing} strain, nu 0.49, {s['spheres']} spheres): "
              f"largest displacement "
              f"difference {m['max_disp_diff_mm']:.3f} mm (stored {want:.3f}, limit {limit:.3f}), "
              f"RMS force error {m['rms_force_N']:.4f} N, inverted steps {s['inverted_steps']}")
        if not m["max_disp_diff_mm"] <= limit:
            failures.append(f"{case}: {m['max_disp_diff_mm']:.3f} mm > {limit:.3f} mm")
        if s["diverged"] or s["inverted_steps"]:
            failures.append(f"{case}: {s['diverged']} diverged, {s['inverted_steps']} inverted")
    out = os.path.join(a.work, "rounded_cylinder_continuum.csv")
    r = subprocess.run([a.indent, scene, "--case", "rounded_cylinder", "--speed", "150", "--law",
                        "continuum", "--nu", "0.49", "--out", out], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"fsm-indent failed ({r.returncode}): {r.stderr}")
    s = json.loads(r.stdout)
    print(f"rounded cylinder (continuum, nu 0.49): force at 2.5 mm {s['final_force_N']:.4f} N, "
          f"deepest sphere centre inside it {1e6 * s['max_penetration_m']:.2f} um "
          f"(limit {1e6 * MAX_PENETRATION_M:g}), {s['diverged']} diverged")
    if not s["max_penetration_m"] <= MAX_PENETRATION_M or s["diverged"]:
        failures.append(f"rounded cylinder: {1e6 * s['max_penetration_m']:.1f} um inside, "
                        f"{s['diverged']} diverged")
    # The rounded cylinder again, on the cylindrical specimen, where it has a converged
    # (axisymmetric) reference: the largest force error from 0.5 to 2.5 mm must stay within
    # `margin` of the stored figure.
    dr, Fr = validate.converged_reference("disc_rounded_cylinder", 0.49)

    def press_specimen(specimen_scene, what, want, margin):
        name = os.path.splitext(os.path.basename(specimen_scene))[0]
        out = os.path.join(a.work, f"{name}_rounded_cylinder_continuum.csv")
        r = subprocess.run([a.indent, specimen_scene, "--case", "rounded_cylinder", "--speed",
                            "150", "--law", "continuum", "--nu", "0.49", "--out", out],
                           capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"fsm-indent failed ({r.returncode}): {r.stderr}")
        s = json.loads(r.stdout)
        d, F = validate.read_curve(out)
        err = validate.max_force_error(d, F, dr, Fr)
        print(f"rounded cylinder on {what} (continuum, nu 0.49, {s['spheres']} spheres): largest "
              f"force error {100 * err:.1f} % (stored {100 * want:.1f} %, limit "
              f"{100 * (want + margin):.1f} %), deepest sphere centre inside it "
              f"{1e6 * s['max_penetration_m']:.2f} um, {s['diverged']} diverged, "
              f"{s['inverted_steps']} inverted")
        if (not err <= want + margin or not s["max_penetration_m"] <= MAX_PENETRATION_M
                or s["diverged"] or s["inverted_steps"]):
            failures.append(f"rounded cylinder on {what}: force error {100 * err:.1f} %, "
                            f"{1e6 * s['max_penetration_m']:.1f} um inside, {s['diverged']} "
                            f"diverged, {s['inverted_steps']} inverted")

    # The coarse specimen (the vertex contact is 45 % low there; docs/validation.md): 5 points.
    disc = os.path.join(a.work, "disc.off")
    scenes.write_disc_off(disc)
    disc_scene = os.path.join(a.work, "coarse_disc.json")
    scenes.write_scene(disc_scene, disc, "tetrahedral", stored["radius_mm"], scenes.LINEAR)
    press_specimen(disc_scene, "the cylindrical specimen",
                   stored["disc_rounded_cylinder"]["max_rel_force_error"], 0.05)
    # The specimen graded toward it (graded_tools.py's filling at h_0 = 0.5 mm): 1 point.
    g = stored["disc_rounded_cylinder_graded"]
    press_specimen(graded_tools.graded_scene(a.work, disc, g["size_min_mm"]),
                   "the specimen graded toward it", g["max_rel_force_error"], 0.01)
    limit = stored["compression"]["max_disp_diff_mm"] + 0.05
    m, _ = run("compression", "links")
    print(f"negative control, the paper's link network: {m['max_disp_diff_mm']:.3f} mm")
    if m["max_disp_diff_mm"] <= limit:
        failures.append("the link network passes the tolerance")
    if failures:
        sys.exit("FAILED: " + "; ".join(failures))
    print("ok")


if __name__ == "__main__":
    main()
