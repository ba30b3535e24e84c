#!/usr/bin/python3
"""Regenerates the reference FEM curves in validation/reference/ with CalculiX.

    /usr/bin/python3 validation/make_reference.py [--quick]

Writes, for each load case (compression, punch):
- reference/<case>_nu<nu>_n<n>.csv: displacement_mm, force_N at 0, 1, ..., 30 s (5 mm/min);
- reference/convergence.csv: the force at 1.25 and 2.5 mm on each mesh (nu = 0.49).
The curves used by the validation are those of REF_N (1 mm elements); the other Poisson
ratios (0.45, 0.47) are run on the middle mesh (NU_N) to keep ccx's time in minutes.
"""

import argparse
import csv
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fem  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
REF_DIR = os.path.join(HERE, "reference")
E_NEO = 13150.0  # Pa: the paper's small-strain modulus as the neo-Hookean reference's E
CONVERGENCE_N = [5, 10, 15]  # elements per 10 mm (quarter model): 2, 1, 0.67 mm
REF_N = 10  # the curves the validation uses (1 mm elements); 15 checks convergence
NU_N = 10  # the other Poisson ratios on the middle mesh (ccx time)
NUS = [0.45, 0.47, 0.49]


def curve_path(case, nu, n):
    return os.path.join(REF_DIR, f"{case}_nu{nu:g}_n{n}.csv")


def write_curve(path, d, F):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["displacement_mm", "force_N"])
        for a, b in zip(d, F):
            w.writerow([f"{a:.6f}", f"{b:.6g}"])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="only the coarse meshes")
    ap.add_argument("--keep", action="store_true", help="keep existing Poisson-ratio curves")
    ap.add_argument("--work", default=os.path.join(HERE, "..", "build-val", "validation-fem"))
    a = ap.parse_args()
    os.makedirs(REF_DIR, exist_ok=True)
    ns = CONVERGENCE_N[:2] if a.quick else CONVERGENCE_N
    rows = []
    for n in ns:
        for case in ("compression", "punch"):
            t0 = time.time()
            d, F = fem.run(a.work, case, n, E_NEO, 0.49)
            sec = time.time() - t0
            write_curve(curve_path(case, 0.49, n), d, F)
            rows.append([case, n, n ** 3, 10.0 / n, F[15], F[-1], sec])
            print(f"{case} n={n}: F(1.25 mm) = {F[15]:.4f} N, F(2.5 mm) = {F[-1]:.4f} N, {sec:.0f} s",
                  flush=True)
            with open(os.path.join(REF_DIR, "convergence.csv"), "w", newline="") as f:
                w = csv.writer(f)
                w.writerow(["case", "n", "elements_quarter", "element_mm", "force_1p25mm_N",
                            "force_2p5mm_N", "seconds"])
                for r in rows:
                    w.writerow([r[0], r[1], r[2], f"{r[3]:.4f}", f"{r[4]:.6g}", f"{r[5]:.6g}",
                                f"{r[6]:.1f}"])
    n_nu = NU_N if NU_N in ns else ns[-1]
    for nu in NUS:
        if nu == 0.49:
            continue
        for case in ("compression", "punch"):
            if a.keep and os.path.exists(curve_path(case, nu, n_nu)):
                continue
            d, F = fem.run(a.work, case, n_nu, E_NEO, nu)
            write_curve(curve_path(case, nu, n_nu), d, F)
            print(f"{case} nu={nu} n={n_nu}: F(2.5 mm) = {F[-1]:.4f} N", flush=True)


if __name__ == "__main__":
    main()
