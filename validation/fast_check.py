#!/usr/bin/python3
"""Fast validation check (ctest `validation_indentation_coarse`, label `validation`).

Builds the coarse block (tetrahedral filling, r = 2 mm, ~580 spheres), runs the compression and
punch cases at 150 mm/min (quasi-static: docs/validation.md measures the rate effect), applies the
stored calibration factor (reference/calibration.json, written by validate.py) and compares with
the stored CalculiX curves. It fails if the largest displacement difference at equal force exceeds
the stored value by more than 0.05 mm (compression) or 0.15 mm (punch, whose contact set of 3-5
spheres makes it sensitive to rounding in the filling). As a negative control it also runs the
compression case with the link stiffness halved and doubled (a factor 2 in the E-to-k rule) and
fails unless the tolerance rejects both, so the check cannot silently lose its teeth.
"""

import argparse
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import scenes  # noqa: E402
import validate  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--indent", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    cal = json.load(open(os.path.join(HERE, "reference", "calibration.json")))
    box = os.path.join(a.work, "box.off")
    scenes.write_box_off(box)
    scene = os.path.join(a.work, "coarse.json")
    scenes.write_scene(scene, box, "tetrahedral", cal["radius_mm"], scenes.LINEAR)
    n = cal["reference_n"]

    def run(case, scale):
        out = os.path.join(a.work, f"{case}_{scale:g}.csv")
        r = subprocess.run([a.indent, scene, "--case", case, "--speed", "150",
                            "--stiffness-scale", f"{scale:.9g}", "--out", out],
                           capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"fsm-indent failed ({r.returncode}): {r.stderr}")
        d, F = validate.read_curve(out)
        dr, Fr = validate.reference(case, 0.49, n)
        return validate.metrics(d, F, dr, Fr)

    failures = []
    s = cal["factor"]
    for case, slack in (("compression", 0.05), ("punch", 0.15)):
        limit = cal[case]["max_disp_diff_mm"] + slack
        m = run(case, s)
        print(f"{case}: largest displacement difference {m['max_disp_diff_mm']:.3f} mm "
              f"(stored {cal[case]['max_disp_diff_mm']:.3f}, limit {limit:.3f}), "
              f"RMS force error {m['rms_force_N']:.4f} N")
        if not m["max_disp_diff_mm"] <= limit:
            failures.append(f"{case}: {m['max_disp_diff_mm']:.3f} mm > {limit:.3f} mm")
    limit = cal["compression"]["max_disp_diff_mm"] + 0.05
    for wrong in (0.5, 2.0):
        m = run("compression", s * wrong)
        print(f"negative control, stiffness x {wrong:g}: {m['max_disp_diff_mm']:.3f} mm")
        if m["max_disp_diff_mm"] <= limit:
            failures.append(f"a factor {wrong:g} in the E-to-k rule passes the tolerance")
    if failures:
        sys.exit("FAILED: " + "; ".join(failures))
    print("ok")


if __name__ == "__main__":
    main()
