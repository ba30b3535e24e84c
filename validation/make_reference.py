#!/usr/bin/python3
"""Regenerates the reference FEM curves in validation/reference/ with CalculiX, and their mesh
convergence study (Richardson extrapolation). See validation/reference/README.md.

    /usr/bin/python3 validation/make_reference.py                 # everything (hours)
    /usr/bin/python3 validation/make_reference.py --cases compression,punch --nus 0.49 --ns 5,10,15
    /usr/bin/python3 validation/make_reference.py --analyse       # only redo the extrapolation

Load cases: "compression" and "punch" (bonded, displacement-driven tools, fem.write_inp) and
"sphere" (R 5 mm), "cylinder" (flat end, R 3 mm, sharp rim) and "rounded_cylinder" (the same
with the rim rounded to 1 mm), rigid frictionless indenters through surface-to-surface penalty
contact (fem.write_contact_inp), and the same three indenters on a cylindrical specimen,
axisymmetric ("disc_sphere", "disc_cylinder", "disc_rounded_cylinder": axisym.write_inp). For
each case, Poisson ratio and mesh:
- reference/<case>_nu<nu>_n<n>.csv: displacement_mm, force_N at every increment (0 included);
  compression/punch with n <= 10 use 30 increments (31 samples, 1 Hz at 5 mm/min, the format the
  validation reads), the other runs --increments (default 10: 0.25 mm steps; the converged
  forces are the same to 6 digits, checked on n = 5);
- reference/runs.json: per run, wall time, increments, solver, largest contact penetration;
and per case and Poisson ratio, from the three finest meshes:
- reference/converged_<case>_nu<nu>.csv: displacement_mm, force_N (Richardson-extrapolated),
  force_uncertainty_N, displacement_uncertainty_mm (= force uncertainty / local slope dF/dd);
- reference/convergence.csv (a row per run) and reference/convergence.json (orders, extrapolated
  values, uncertainties, times).
ccx runs single-threaded, one at a time, niced.
"""

import argparse
import csv
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import axisym  # noqa: E402
import fem  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
REF_DIR = os.path.join(HERE, "reference")
E_NEO = 13150.0  # Pa: the paper's small-strain modulus as the neo-Hookean reference's E
CASES = ["compression", "compression_graded", "punch", "sphere", "cylinder", "rounded_cylinder",
         "disc_rounded_cylinder", "disc_cylinder", "disc_sphere"]
# Bonded, displacement-driven cases (fem.write_inp); "compression_graded" is the compression on a
# mesh family graded toward its singular edges (fem.edge_graded).
BONDED = ("compression", "compression_graded", "punch")
NUS = [0.49, 0.45]
NS = [5, 10, 15, 20]  # elements per 10 mm (quarter model): 2, 1, 0.67, 0.5 mm (nominal)
# The contact runs cost about 4x a bonded run of the same mesh (8-10 Newton iterations per
# increment); their family is n = 5, 7, 10 (graded, see fem.block_mesh) within the time budget.
NS_CONTACT = [5, 7, 10]
# The cylindrical specimen's axisymmetric section (validation/axisym.py): n x n CAX8 elements.
NS_DISC = [10, 15, 20, 25]
LEGACY_N = 10  # compression/punch with n <= LEGACY_N: 30 increments (the validation's curves)
FS = 1.25  # safety factor of the grid convergence index (three meshes, Roache)
P_RANGE = (0.5, 3.0)  # plausible observed orders; outside: clipped and flagged
DEPTH_MM = 2.5


def curve_path(case, nu, n):
    return os.path.join(REF_DIR, f"{case}_nu{nu:g}_n{n}.csv")


def write_curve(path, d, F):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["displacement_mm", "force_N"])
        for a, b in zip(d, F):
            w.writerow([f"{a:.6f}", f"{b:.6g}"])


def read_curve(path):
    with open(path) as f:
        rows = list(csv.reader(f))[1:]
    a = np.array([[float(x) for x in r] for r in rows])
    return a[:, 0], a[:, 1]


def load_runs():
    p = os.path.join(REF_DIR, "runs.json")
    return json.load(open(p)) if os.path.exists(p) else {}


def save_runs(runs):
    """Merges `runs` into reference/runs.json (several invocations may run one after another)."""
    merged = load_runs()
    merged.update(runs)
    with open(os.path.join(REF_DIR, "runs.json"), "w") as f:
        json.dump(merged, f, indent=1, sort_keys=True)


def run_key(case, nu, n):
    return f"{case}_nu{nu:g}_n{n}"


def run_one(a, case, nu, n):
    incs = 30 if case in ("compression", "punch") and n <= LEGACY_N else a.increments
    solver = {"spooles": None, "iterative": "ITERATIVE CHOLESKY"}[a.solver]
    t0 = time.time()
    if case in BONDED:
        d, F = fem.run(a.work, case, n, E_NEO, nu, samples=incs, solver=solver, ccx=a.ccx,
                       refine=(1,) if a.keep_partial else (1, 2, 3), keep_partial=a.keep_partial)
        incs *= fem.run.last_refine
        pen = pen_rel = None
    elif a.contact_increments:
        # The contact force depends on the increment size (about first order: ccx pairs the
        # slave and master surfaces at the start of each increment). Two runs with k and 2k
        # increments per sample, and F = 2 F_2k - F_k at every sample (p = 1); the pair is
        # stored beside the curve (increments_path) and its spread enters the uncertainty.
        k1 = a.contact_increments
        runs_k = []
        runner = axisym.run_contact if case in axisym.CASES else fem.run_contact
        for k in (k1, 2 * k1):
            d, F, p, _ = runner(a.work, case, n, E_NEO, nu, samples=incs, solver=solver,
                                penalty=a.penalty, ccx=a.ccx, refine=(k,))
            runs_k.append((d, F, p))
        (d, F1, p1), (_, F2, p2) = runs_k
        F = 2 * F2 - F1
        with open(increments_path(case, nu, n), "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["displacement_mm", f"force_N_{incs * k1}_increments",
                        f"force_N_{incs * 2 * k1}_increments", "force_N_extrapolated"])
            for row in zip(d, F1, F2, F):
                w.writerow([f"{row[0]:.6f}"] + [f"{x:.6g}" for x in row[1:]])
        incs = [incs * k1, incs * 2 * k1]
        pen = float(max(np.max(p1), np.max(p2)))
        pen_rel = float(np.max(np.maximum(p1, p2)[1:] / d[1:]))
    else:
        runner = axisym.run_contact if case in axisym.CASES else fem.run_contact
        d, F, p, k = runner(a.work, case, n, E_NEO, nu, samples=incs, solver=solver,
                            penalty=a.penalty, ccx=a.ccx)
        incs *= k
        pen = float(np.max(p))
        pen_rel = float(np.max(p[1:] / d[1:]))
    sec = time.time() - t0
    partial = case in BONDED and fem.run.partial
    return d, F, {"seconds": round(sec, 1), "increments": incs, "solver": a.solver,
                  "partial_to_mm": float(d[-1]) if partial else None,
                  "max_penetration_mm": pen, "element_mm": 10.0 / n,
                  "max_penetration_over_displacement": None if pen is None else pen_rel,
                  "when": time.strftime("%Y-%m-%d %H:%M")}


# ------------------------------------------------------------------------- Richardson analysis

def observed_order(h, f):
    """Observed order p from three meshes h[0] > h[1] > h[2] (any ratios), values f; None if the
    convergence is not monotone or no p in (0.05, 10) fits."""
    e21, e32 = f[1] - f[0], f[2] - f[1]
    if e21 == 0 or e32 == 0 or np.sign(e21) != np.sign(e32):
        return None
    target = e21 / e32

    def g(p):
        return (h[0] ** p - h[1] ** p) / (h[1] ** p - h[2] ** p)

    lo, hi = 0.05, 10.0
    if not (g(lo) <= target <= g(hi)):
        return None
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if g(mid) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def extrapolate(h, f):
    """(extrapolated value, uncertainty, observed p or None, method) from three meshes."""
    p = observed_order(h, f)
    r = h[1] / h[2]
    if p is None:
        # oscillating / diverging: the finest value, +- the difference of the two finest
        return f[2], abs(f[2] - f[1]), None, "non-monotone: finest mesh +- |F_finest - F_second|"
    pu = min(max(p, P_RANGE[0]), P_RANGE[1])
    fe = f[2] + (f[2] - f[1]) / (r ** pu - 1)
    u = FS * abs(fe - f[2])
    if pu != p:
        u = max(u, abs(f[2] - f[1]))
        return fe, u, p, f"p clipped to {pu:g}; uncertainty max(GCI, |F_finest - F_second|)"
    return fe, u, p, "Richardson, GCI (Fs = 1.25)"


def increments_path(case, nu, n):
    return os.path.join(REF_DIR, f"{case}_nu{nu:g}_n{n}_increments.csv")


# Share of |F_2k - F_k| (the increment correction) taken as the uncertainty of the increment
# extrapolation: on rounded_cylinder n = 5 (nu 0.49, 25 MPa/mm) 10, 20 and 40 increments gave
# F(2.5 mm) = 0.29287, 0.28774, 0.28500 N, a ratio of successive differences of 1.87 where p = 1
# gives 2, so the p = 1 extrapolation is off by about 15 % of its correction.
INC_SHARE = 0.25


def increment_uncertainty(case, nu, n, x):
    """INC_SHARE |F_2k - F_k| at displacement x for a run with an increments file, else 0."""
    path = increments_path(case, nu, n)
    if not os.path.exists(path):
        return 0.0
    t = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return INC_SHARE * float(np.interp(x, t[:, 0], np.abs(t[:, 2] - t[:, 1])))


def partial_path(case, nu, n):
    return os.path.join(REF_DIR, f"{case}_nu{nu:g}_n{n}_partial.csv")


def extrapolate2(h, f, p):
    """Two meshes h[0] > h[1] with an assumed order p (the last one observed on three meshes):
    (value, uncertainty = max(Fs |F_ext - F_fine|, |F_fine - F_coarse|), p, method)."""
    r = h[0] / h[1]
    fe = f[1] + (f[1] - f[0]) / (r ** p - 1)
    return fe, max(FS * abs(fe - f[1]), abs(f[1] - f[0])), p, \
        f"two meshes (finest incomplete), p = {p:.3g} assumed; uncertainty max(GCI, |F_fine - F_coarse|)"


def analyse(a, runs):
    """Per case and Poisson ratio, the three finest meshes (a run that stopped early, kept as
    <case>_nu<nu>_n<n>_partial.csv, counts where it has samples; past its end the two finest
    meshes that have the sample are extrapolated with the last observed order, and where fewer
    than two have it the converged curve ends: `reaches_mm`)."""
    summary, conv_rows = {}, []
    for case in CASES:
        for nu in NUS:
            full = [n for n in range(2, 161) if os.path.exists(curve_path(case, nu, n))]
            for n in full:
                d, F = read_curve(curve_path(case, nu, n))
                r = runs.get(run_key(case, nu, n), {})
                elements = n ** 2 if case in axisym.CASES else n ** 3  # a section or a quarter
                conv_rows.append([case, nu, n, elements, 10.0 / n, np.interp(1.25, d, F),
                                  np.interp(2.5, d, F), r.get("seconds"), r.get("increments"),
                                  r.get("max_penetration_mm")])
            # A run that stopped early (<case>_nu<nu>_n<n>_partial.csv) counts where it has samples.
            part = [n for n in range(2, 161) if n not in full
                    and os.path.exists(partial_path(case, nu, n))]
            ns = sorted(full + part)
            if len(ns) < 3:
                continue
            use = ns[-3:]
            curves = [read_curve(partial_path(case, nu, n) if n in part else curve_path(case, nu, n))
                      for n in use]
            h = [10.0 / n for n in use]

            def has(c, x):
                return np.min(np.abs(c[0] - x)) < 1e-5

            # Output grid: the samples of the densest of the curves that reach furthest. At each
            # sample, the three meshes where all have it; else the two finest that have it with
            # the last observed order; where fewer than two have it, the converged curve ends.
            reach = max(c[0][-1] for c in curves)
            furthest = [i for i in range(3) if curves[i][0][-1] > reach - 1e-6]
            dense = max(furthest, key=lambda i: (len(curves[i][0]), use[i]))
            dd, FF = curves[dense]
            rows, p_last = [], None
            for x in dd:
                if x == 0:
                    rows.append((0.0, [0.0] * 3, 0.0, 0.0, None, "zero"))
                    continue
                avail = [i for i in range(3) if has(curves[i], x)]
                f = [float(np.interp(x, c[0], c[1])) if i in avail else None
                     for i, c in enumerate(curves)]
                if len(avail) == 3:
                    fe, u, p, how = extrapolate(h, f)
                    if p is not None:
                        p_last = min(max(p, P_RANGE[0]), P_RANGE[1])
                elif len(avail) == 2 and p_last is not None and \
                        all(x > c[0][-1] + 1e-9 for i, c in enumerate(curves) if i not in avail):
                    fe, u, p, how = extrapolate2([h[i] for i in avail], [f[i] for i in avail],
                                                 p_last)
                elif sum(x > c[0][-1] + 1e-9 for c in curves) >= 2:
                    break  # fewer than two meshes reach this far
                else:
                    continue  # a sample that a coarser increment grid does not have

                # the increment extrapolation's own uncertainty (contact runs made with
                # --contact-increments), the largest of the meshes used, added
                u_inc = max(increment_uncertainty(case, nu, use[i], x) for i in avail)
                if u_inc > 0:
                    u, how = u + u_inc, how + f"; + increment extrapolation {u_inc:.2g} N"
                rows.append((float(x), f, fe, u, p, how))
            dd, FF = dd[dd <= rows[-1][0] + 1e-9], FF[dd <= rows[-1][0] + 1e-9]
            dc = np.array([r[0] for r in rows])
            fe = np.array([r[2] for r in rows])
            ue = np.array([r[3] for r in rows])
            # between the extrapolated samples: the correction (F_ext - F_dense) and the
            # uncertainty are interpolated linearly
            corr = fe - np.interp(dc, dd, FF)
            F_out = FF + np.interp(dd, dc, corr)
            U_out = np.interp(dd, dc, ue)
            slope = np.gradient(F_out, dd)
            Ud_out = np.where(slope > 0, U_out / np.maximum(slope, 1e-12), np.nan)
            Ud_out[0] = 0.0
            with open(os.path.join(REF_DIR, f"converged_{case}_nu{nu:g}.csv"), "w", newline="") as f:
                w = csv.writer(f)
                w.writerow(["displacement_mm", "force_N", "force_uncertainty_N",
                            "displacement_uncertainty_mm"])
                for x, y, u, ud in zip(dd, F_out, U_out, Ud_out):
                    w.writerow([f"{x:.6f}", f"{y:.6g}", f"{u:.3g}", f"{ud:.3g}"])
            slope_c = np.interp(dc, dd, slope)
            key = f"{case}_nu{nu:g}"
            summary[key] = {
                "case": case, "nu": nu, "meshes_n": use, "element_mm": h,
                "partial_finest": bool(use[-1] in part),
                "finest_reaches_mm": float(curves[2][0][-1]),
                "reaches_mm": float(dd[-1]),
                "all_meshes_n": ns,
                "seconds": [runs.get(run_key(case, nu, n), {}).get("seconds") for n in use],
                "increments": [runs.get(run_key(case, nu, n), {}).get("increments") for n in use],
                "max_penetration_mm": [runs.get(run_key(case, nu, n), {}).get("max_penetration_mm")
                                       for n in use],
                "output_grid_from_n": use[dense],
                "samples": [{"displacement_mm": r[0], "force_N_per_mesh": r[1],
                             "observed_order": r[4], "force_extrapolated_N": float(r[2]),
                             "force_uncertainty_N": float(r[3]),
                             "displacement_uncertainty_mm": (float(r[3] / s) if s > 0 and r[0] > 0
                                                             else 0.0),
                             "method": r[5]} for r, s in zip(rows, slope_c)],
            }
            for x in (1.25, 2.5):
                k = int(np.argmin(np.abs(dc - x)))
                s_ = summary[key]["samples"][k]
                summary[key][f"at_{x:g}mm"] = s_
                print(f"{case} nu={nu:g} n={use}: d={s_['displacement_mm']:.3g} mm "
                      f"F={s_['force_N_per_mesh']} -> {s_['force_extrapolated_N']:.5g} +- "
                      f"{s_['force_uncertainty_N']:.2g} N ({s_['displacement_uncertainty_mm']:.3g} mm), "
                      f"p={s_['observed_order']}, {s_['method']}")
    with open(os.path.join(REF_DIR, "convergence.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["case", "nu", "n", "elements_quarter", "element_mm", "force_1p25mm_N",
                    "force_2p5mm_N", "seconds", "increments", "max_penetration_mm"])
        for r in conv_rows:
            w.writerow([r[0], f"{r[1]:g}", r[2], r[3], f"{r[4]:.4f}", f"{r[5]:.6g}", f"{r[6]:.6g}",
                        "" if r[7] is None else f"{r[7]:.1f}", "" if r[8] is None else r[8],
                        "" if r[9] is None else f"{r[9]:.2g}"])
    with open(os.path.join(REF_DIR, "convergence.json"), "w") as f:
        json.dump({"E_pa": E_NEO, "safety_factor": FS, "p_range": P_RANGE,
                   "uncertainty": "GCI = Fs |F_ext - F_finest| (Roache, three meshes); see README",
                   "studies": summary, "runs": runs}, f, indent=1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--nus", default=",".join(f"{x:g}" for x in NUS))
    ap.add_argument("--ns", default=None, help="meshes (default: 5,10,15,20 for compression "
                    "and punch, 5,7,10 for the contact cases, 10,15,20,25 for the disc cases)")
    ap.add_argument("--increments", type=int, default=10,
                    help="fixed increments of the runs other than compression/punch n <= 10")
    ap.add_argument("--solver", choices=["spooles", "iterative"], default="spooles")
    ap.add_argument("--penalty", type=float, default=None,
                    help="contact, MPa/mm (default fem.PENALTY: sphere 50, cylinder 10, "
                    "rounded_cylinder 25)")
    ap.add_argument("--contact-increments", type=int, default=2,
                    help="contact cases: k; each mesh runs with k and 2k increments per sample "
                    "and the force is extrapolated to zero increment size (0: one run, retried "
                    "with more increments if it fails, as before 2026-11-26)")
    ap.add_argument("--reuse", action="store_true", help="skip runs whose curve file exists")
    ap.add_argument("--keep-partial", action="store_true",
                    help="bonded cases: one attempt, no retries with more increments; a run that "
                    "stops early is kept as <case>_nu<nu>_n<n>_partial.csv")
    ap.add_argument("--analyse", action="store_true", help="no ccx: only the extrapolation")
    ap.add_argument("--deadline", type=float, default=0,
                    help="seconds: start no new run after this much wall time")
    ap.add_argument("--ccx", default="/usr/bin/ccx")
    ap.add_argument("--work", default=os.path.join(HERE, "..", "build-val", "validation-fem"))
    a = ap.parse_args()
    os.makedirs(REF_DIR, exist_ok=True)
    cases = a.cases.split(",")
    nus = [float(x) for x in a.nus.split(",")]
    ns_all = ([int(x) for x in a.ns.split(",")] if a.ns
              else sorted(set(NS) | set(NS_CONTACT) | set(NS_DISC)))
    runs = load_runs()
    t_start = time.time()
    if not a.analyse:
        for n in ns_all:  # coarse meshes of every case first: a budget cut loses the finest
            for nu in nus:
                for case in cases:
                    family = (NS if case in BONDED else NS_DISC if case in axisym.CASES
                              else NS_CONTACT)
                    if not a.ns and n not in family:
                        continue
                    if a.reuse and (os.path.exists(curve_path(case, nu, n)) or
                                    (a.keep_partial and os.path.exists(partial_path(case, nu, n)))):
                        continue
                    if a.deadline and time.time() - t_start > a.deadline:
                        print(f"deadline: {case} nu={nu:g} n={n} not run", flush=True)
                        continue
                    try:
                        d, F, info = run_one(a, case, nu, n)
                    except RuntimeError as e:
                        print(f"{case} nu={nu:g} n={n}: FAILED {e}", flush=True)
                        runs[run_key(case, nu, n)] = {"failed": str(e)[:500]}
                        save_runs({run_key(case, nu, n): runs[run_key(case, nu, n)]})
                        continue
                    write_curve(partial_path(case, nu, n) if info["partial_to_mm"] is not None
                                else curve_path(case, nu, n), d, F)
                    runs[run_key(case, nu, n)] = info
                    save_runs({run_key(case, nu, n): info})
                    print(f"{case} nu={nu:g} n={n}: F(1.25 mm) = {np.interp(1.25, d, F):.5g} N, "
                          f"F({d[-1]:.4g} mm) = {F[-1]:.5g} N, {info['seconds']:.0f} s, pen "
                          f"{info['max_penetration_mm']}", flush=True)
    analyse(a, load_runs())


if __name__ == "__main__":
    main()
