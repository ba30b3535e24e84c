#!/usr/bin/python3
"""The validation harness: runs the indentation experiment on built models, calibrates the one
global stiffness factor on the compression case, predicts the punch case, measures the volume
term and the speed/accuracy of integrators, fillings and resolutions, and draws the charts.

    /usr/bin/python3 validation/validate.py --indent BUILD/validation/fsm-indent \
        [--stability BUILD/validation/fsm-stability-map] [--only main,volume,sweep,stability]

Writes validation/results/*.json and docs/img/validation_*.png (docs/validation.md).
"""

import argparse
import csv
import json
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import scenes  # noqa: E402

ROOT = os.path.dirname(HERE)
REF_DIR = os.path.join(HERE, "reference")
RES_DIR = os.path.join(HERE, "results")
IMG_DIR = os.path.join(ROOT, "docs", "img")
REF_N = int(os.environ.get("FSM_REF_N", 10))  # reference mesh (make_reference.py: n = 10, 1 mm)
NU_N = 10           # mesh of the Poisson-ratio study
HAPTIC_R = 1.85     # mm: about 700 spheres
SPEED_FAST = 150.0  # mm/min: the sweeps load in 1 s; checked against 5 mm/min in "main"


def converged_reference(case, nu=0.49):
    """The Richardson-extrapolated CalculiX curve (reference/converged_<case>_nu<nu>.csv):
    displacement (mm) and force (N) arrays."""
    with open(os.path.join(REF_DIR, f"converged_{case}_nu{nu:g}.csv")) as f:
        rows = list(csv.DictReader(f))
    return (np.array([float(r["displacement_mm"]) for r in rows]),
            np.array([float(r["force_N"]) for r in rows]))


def interp_power(x, dr, Fr):
    """The reference's force at displacements x, interpolated as a power law F = a d^p between
    neighbouring samples (linear in log-log; the first interval takes the exponent of the next).
    A reference sampled every 0.25 mm is convex near the start (a ball's force grows as d^1.5):
    a straight chord between samples overstates it by up to 2 % between 0.5 and 0.75 mm, which
    a linear interpolation would count as the model's error. Falls back to linear interpolation
    where the samples are not positive and increasing."""
    x = np.asarray(x, dtype=float)
    lin = np.interp(x, dr, Fr)
    ok = (dr > 0) & (Fr > 0)
    d, F = dr[ok], Fr[ok]
    if len(d) < 2 or np.any(np.diff(d) <= 0) or np.any(np.diff(F) <= 0):
        return lin
    ld, lF = np.log(d), np.log(F)
    slopes = np.diff(lF) / np.diff(ld)
    inside = (x > 0) & (x <= d[-1])
    xi = x[inside]
    # The interval of each x (below the first positive sample: the first interval's power law).
    k = np.clip(np.searchsorted(d, xi) - 1, 0, len(d) - 2)
    out = lin.copy()
    out[inside] = np.exp(lF[k] + slopes[k] * (np.log(xi) - ld[k]))
    return out


def read_curve(path):
    with open(path) as f:
        rows = list(csv.reader(f))[1:]
    a = np.array([[float(x) for x in r] for r in rows])
    return a[:, 0], a[:, 1]


def reference(case, nu=0.49, n=REF_N):
    return read_curve(os.path.join(REF_DIR, f"{case}_nu{nu:g}_n{n}.csv"))


def first_crossing(d, F, f):
    """Smallest displacement at which the curve (d, F) reaches force f (linear interpolation);
    NaN if it never does."""
    idx = np.nonzero(F >= f)[0]
    if len(idx) == 0:
        return np.nan
    k = idx[0]
    if k == 0:
        return d[0]
    t = (f - F[k - 1]) / (F[k] - F[k - 1])
    return d[k - 1] + t * (d[k] - d[k - 1])


def max_force_error(d, F, dr, Fr, lo=0.5, hi=2.5):
    """The smooth indenters' target metric: the largest |F / F_ref - 1| over the model's samples
    from lo to hi mm, the reference interpolated as a power law (interp_power)."""
    mask = (d >= lo - 1e-9) & (d <= hi + 1e-9)
    return float(np.max(np.abs(F[mask] / interp_power(d[mask], dr, Fr) - 1)))


def metrics(dm, Fm, dr, Fr):
    """The paper's metric, the largest displacement difference at equal force over the
    reference's force range (mm), and the RMS force error at the reference's displacements (N).
    Where the model never reaches a force of the range the difference is taken to the end of the
    loading (2.5 mm), a lower bound, and `covered` says which share of the range was reached."""
    levels = np.linspace(0, Fr.max(), 200)[1:]
    diffs, reached = [], 0
    for f in levels:
        a = first_crossing(dm, Fm, f)
        b = first_crossing(dr, Fr, f)
        if np.isnan(a):
            a = dm[-1]
        else:
            reached += 1
        diffs.append(abs(a - b))
    Fi = np.interp(dr, dm, Fm)
    return {"max_disp_diff_mm": float(np.max(diffs)),
            "rms_force_N": float(np.sqrt(np.mean((Fi - Fr) ** 2))),
            "covered": reached / len(levels)}


def calibrate(dm, Fm, dr, Fr):
    """The global factor s (forces scale exactly with s: every link constant, and the volume
    term's kappa, is proportional to it, and the loading is quasi-static) minimising the largest
    displacement difference on this case."""
    grid = np.exp(np.linspace(np.log(0.2), np.log(20), 400))
    errs = [metrics(dm, s * Fm, dr, Fr)["max_disp_diff_mm"] for s in grid]
    k = int(np.argmin(errs))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    for _ in range(40):  # golden section on the bracket
        a = hi - 0.618 * (hi - lo)
        b = lo + 0.618 * (hi - lo)
        if metrics(dm, a * Fm, dr, Fr)["max_disp_diff_mm"] < metrics(dm, b * Fm, dr, Fr)["max_disp_diff_mm"]:
            hi = b
        else:
            lo = a
    return 0.5 * (lo + hi)


class Runner:
    def __init__(self, indent, work):
        self.indent = indent
        self.work = work
        os.makedirs(work, exist_ok=True)
        self.box = os.path.join(work, "box.off")
        scenes.write_box_off(self.box)

    def scene(self, topology="tetrahedral", radius=HAPTIC_R, material="linear", spacing=None):
        name = f"{topology}_r{radius:g}" + (f"_s{spacing:g}" if spacing else "") + f"_{material}"
        path = os.path.join(self.work, name + ".json")
        if not os.path.exists(path):
            mat = scenes.LINEAR if material == "linear" else scenes.BILINEAR
            scenes.write_scene(path, self.box, topology, radius, mat, grid_spacing=spacing)
        return path

    def run(self, scene, case, speed=SPEED_FAST, **opts):
        tag = os.path.basename(scene)[:-5] + f"_{case}_v{speed:g}" + "".join(
            f"_{k}{v}" for k, v in sorted(opts.items()))
        out = os.path.join(self.work, tag + ".csv")
        info_path = os.path.join(self.work, tag + ".json")
        if os.path.exists(info_path) and os.path.exists(out):
            info = json.load(open(info_path))
        else:
            cmd = [self.indent, scene, "--case", case, "--speed", str(speed), "--out", out]
            for k, v in opts.items():
                cmd += ["--" + k.replace("_", "-"), str(v)]
            t0 = time.time()
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode not in (0, 3):
                raise RuntimeError(" ".join(cmd) + "\n" + r.stderr)
            info = json.loads(r.stdout.strip().splitlines()[-1])
            info["wall_s"] = time.time() - t0
            json.dump(info, open(info_path, "w"))
            print(f"  {tag}: {info['spheres']} spheres, F_end {info['final_force_N']:.4g} N, "
                  f"{info['mean_step_us']:.0f} us/step, dt {info['dt']:.3g}", flush=True)
        d, F = read_curve(out) if info.get("finite", True) else (np.array([0.0]), np.array([0.0]))
        return d, F, info


def study_main(R):
    """Tetrahedral fillings at several radii: calibrate on compression, predict the punch."""
    dc, Fc = reference("compression")
    dp, Fp = reference("punch")
    rows = []
    for r in (1.25, 1.5, HAPTIC_R, 2.0, 2.5):
        sc = R.scene("tetrahedral", r)
        d1, F1, ic = R.run(sc, "compression")
        d2, F2, ip = R.run(sc, "punch")
        s = calibrate(d1, F1, dc, Fc)
        row = {"radius_mm": r, "spheres": ic["spheres"], "links": ic["links"],
               "tetrahedra": ic["tetrahedra"], "punch_spheres": ip["driven"], "factor": s,
               "step_us": ic["median_step_us"],
               "compression_raw": metrics(d1, F1, dc, Fc),
               "compression": metrics(d1, s * F1, dc, Fc),
               "punch_raw": metrics(d2, F2, dp, Fp),
               "punch": metrics(d2, s * F2, dp, Fp)}
        rows.append(row)
        print(f"  r={r}: factor {s:.3f}, compression {row['compression']}, punch {row['punch']}")
    # Rate check (the sweeps load at 150 mm/min) and the exactness of the force scaling.
    sc = R.scene("tetrahedral", HAPTIC_R)
    checks = {}
    for case in ("compression", "punch"):
        df, Ff, _ = R.run(sc, case)
        ds, Fs, _ = R.run(sc, case, speed=5.0)
        checks[f"{case}_rate_max_force_rel"] = float(np.max(np.abs(Ff - Fs)[1:] / np.abs(Fs[1:])))
    s = next(r["factor"] for r in rows if r["radius_mm"] == HAPTIC_R)
    d1, F1, _ = R.run(sc, "compression")
    ds, Fs, _ = R.run(sc, "compression", stiffness_scale=round(s, 6))
    checks["scaling_max_force_rel"] = float(np.max(np.abs(round(s, 6) * F1 - Fs)[1:] / Fs[1:]))
    return {"rows": rows, "checks": checks}


def study_volume(R):
    """The volume term at nu = 0.45, 0.47, 0.49 against references of the same nu."""
    sc = R.scene("tetrahedral", HAPTIC_R)
    rows = []
    for nu in (0.45, 0.47, 0.49):
        dc, Fc = reference("compression", nu, NU_N)
        dp, Fp = reference("punch", nu, NU_N)
        for with_term in (False, True):
            opts = {"poisson": nu, "dt_fraction": 0.8} if with_term else {}
            d1, F1, ic = R.run(sc, "compression", **opts)
            d2, F2, ip = R.run(sc, "punch", **opts)
            s = calibrate(d1, F1, dc, Fc)
            rows.append({"nu": nu, "volume_term": with_term, "factor": s,
                         "kappa_Pa": ic["kappa"], "dt": ic["dt"], "step_us": ic["median_step_us"],
                         "volume_us": ic["volume_term_us"], "omega_volume": ic["omega_volume"],
                         "compression": metrics(d1, s * F1, dc, Fc),
                         "punch": metrics(d2, s * F2, dp, Fp)})
            print(f"  nu={nu} term={with_term}: factor {s:.3f} punch {rows[-1]['punch']}")
    return {"rows": rows, "radius_mm": HAPTIC_R, "reference_n": NU_N}


def study_sweep(R):
    """Speed against accuracy: integrator x step x resolution x filling; the error is the punch
    prediction's after calibration on compression."""
    dc, Fc = reference("compression")
    dp, Fp = reference("punch")
    fillings = [("tetrahedral", HAPTIC_R, None), ("tetrahedral", 2.5, None),
                ("tetrahedral", 3.0, None), ("grid", 1.0, 2.0), ("grid", 1.25, 2.5),
                ("grid", 1.67, 3.33)]
    schemes = [("implicit_euler", {"dt": 1e-3}), ("implicit_euler", {"dt": 2.5e-4}),
               ("symplectic_euler", {"dt_fraction": 0.9}), ("symplectic_euler", {"dt_fraction": 0.45}),
               ("improved_euler", {"dt_fraction": 0.9}), ("heun", {"dt_fraction": 0.9})]
    rows = []
    for topo, r, s in fillings:
        sc = R.scene(topo, r, spacing=s)
        for integ, opts in schemes:
            o = dict(opts, integrator=integ)
            d1, F1, ic = R.run(sc, "compression", **o)
            d2, F2, ip = R.run(sc, "punch", **o)
            ok = ic["finite"] and ip["finite"] and ic["diverged"] == 0 and ip["diverged"] == 0
            row = {"filling": topo, "radius_mm": r, "spacing_mm": s, "integrator": integ,
                   "dt": ic["dt"], "spheres": ic["spheres"], "links": ic["links"],
                   "step_us": ic["median_step_us"],
                   "us_per_sim_ms": ic["median_step_us"] * 1e-3 / ic["dt"], "ok": ok,
                   "punch_spheres": ip["driven"]}
            if ok:
                f = calibrate(d1, F1, dc, Fc)
                row.update(factor=f, compression=metrics(d1, f * F1, dc, Fc),
                           punch=metrics(d2, f * F2, dp, Fp))
            rows.append(row)
    return {"rows": rows}


def study_stability(R, exe):
    r = subprocess.run([exe, R.scene("tetrahedral", 2.5)], capture_output=True, text=True,
                       check=True)
    return json.loads(r.stdout)


# ---------------------------------------------------------------------------------------------
# Charts


def charts(R, res):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    os.makedirs(IMG_DIR, exist_ok=True)

    if "main" in res:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
        main = {r["radius_mm"]: r for r in res["main"]["rows"]}
        s = main[HAPTIC_R]["factor"]
        sc = R.scene("tetrahedral", HAPTIC_R)
        scb = R.scene("tetrahedral", HAPTIC_R, material="bilinear")
        vol = None
        if "volume" in res:
            vol = next(r for r in res["volume"]["rows"] if r["nu"] == 0.49 and r["volume_term"])
        for ax, case in zip(axes, ("compression", "punch")):
            dr, Fr = reference(case)
            ax.plot(dr, Fr, "k-", lw=2.5, label=f"CalculiX neo-Hookean, nu 0.49 (n={REF_N})")
            d, F, _ = R.run(sc, case)
            ax.plot(d, F, "C0--", label="spheres, E-to-k rule as is")
            ax.plot(d, s * F, "C0-", label=f"spheres x {s:.2f} (fitted on compression)")
            if vol:
                d, F, _ = R.run(sc, case, poisson=0.49, dt_fraction=0.8)
                ax.plot(d, vol["factor"] * F, "C2-",
                        label=f"+ volume term nu 0.49, x {vol['factor']:.2f}")
            d, F, _ = R.run(scb, case)
            ax.plot(d, F, "C3:", label="bilinear 13.15/68.38 kPa (paper), as is")
            ax.set_title(f"{case} (r = {HAPTIC_R} mm, {main[HAPTIC_R]['spheres']} spheres)")
            ax.set_xlabel("displacement (mm)")
            ax.set_ylabel("force (N)")
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=7.5, loc="upper left")
        fig.tight_layout()
        fig.savefig(os.path.join(IMG_DIR, "validation_force_displacement.png"), dpi=120)
        plt.close(fig)

        # Reference convergence
        conv = list(csv.DictReader(open(os.path.join(REF_DIR, "convergence.csv"))))
        fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
        for ax, case in zip(axes, ("compression", "punch")):
            for row in [c for c in conv if c["case"] == case and float(c["nu"]) == 0.49]:
                path = os.path.join(REF_DIR, f"{case}_nu0.49_n{int(row['n'])}.csv")
                if not os.path.exists(path):  # a run that did not finish (reference/README.md)
                    continue
                d, F = reference(case, 0.49, int(row["n"]))
                ax.plot(d, F, label=f"{float(row['element_mm']):.2f} mm elements")
            conv_path = os.path.join(REF_DIR, f"converged_{case}_nu0.49.csv")
            if os.path.exists(conv_path):
                rows = list(csv.DictReader(open(conv_path)))
                ax.plot([float(r["displacement_mm"]) for r in rows],
                        [float(r["force_N"]) for r in rows], "k--", label="extrapolated")
            ax.set_title(f"reference {case}: mesh convergence")
            ax.set_xlabel("displacement (mm)")
            ax.set_ylabel("force (N)")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(os.path.join(IMG_DIR, "validation_reference_convergence.png"), dpi=110)
        plt.close(fig)

    if "sweep" in res:
        fig, ax = plt.subplots(figsize=(10.5, 5))
        marks = {"implicit_euler": "o", "symplectic_euler": "s", "improved_euler": "^", "heun": "D"}
        colors = {}
        for row in res["sweep"]["rows"]:
            if not row["ok"]:
                continue
            key = (row["filling"], row["radius_mm"], row["spacing_mm"])
            if key not in colors:
                colors[key] = f"C{len(colors)}"
            ax.scatter(row["us_per_sim_ms"] / 1e3, row["punch"]["max_disp_diff_mm"],
                       marker=marks[row["integrator"]], color=colors[key], s=40,
                       facecolors="none" if row["dt"] < 0.5 * max(
                           r["dt"] for r in res["sweep"]["rows"]
                           if r["integrator"] == row["integrator"] and
                           (r["filling"], r["radius_mm"], r["spacing_mm"]) == key) else colors[key])
        for key, c in colors.items():
            n = next(r["spheres"] for r in res["sweep"]["rows"]
                     if (r["filling"], r["radius_mm"], r["spacing_mm"]) == key)
            lab = (f"tetrahedral r {key[1]} mm" if key[0] == "tetrahedral"
                   else f"grid {key[2]} mm") + f" ({n} spheres)"
            ax.scatter([], [], color=c, marker="o", label=lab)
        for name, m in marks.items():
            ax.scatter([], [], color="gray", marker=m, label=name)
        ax.axvline(1.0, color="k", ls=":", lw=1)
        ax.text(1.05, 0.06, "1 kHz haptic budget (1 ms per ms)", fontsize=8)
        ax.text(0.02, 0.052, "target 0.05 mm", fontsize=8, color="r")
        ax.axhline(0.05, color="r", ls=":", lw=1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("cost per simulated millisecond (ms of CPU, one thread)")
        ax.set_ylabel("punch: largest displacement difference (mm)")
        ax.set_title("speed against accuracy (filled: larger step, hollow: smaller step)")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        fig.tight_layout()
        fig.savefig(os.path.join(IMG_DIR, "validation_speed_accuracy.png"), dpi=120)
        plt.close(fig)

    if "stability" in res:
        st = res["stability"]
        names = sorted({r["integrator"] for r in st["rows"]})
        fig, axes = plt.subplots(1, len(names), figsize=(4 * len(names), 3.8), sharey=True)
        for ax, name in zip(np.atleast_1d(axes), names):
            rows = [r for r in st["rows"] if r["integrator"] == name]
            etas = sorted({r["viscosity"] for r in rows})
            for k, eta in enumerate(etas):
                rr = sorted([r for r in rows if r["viscosity"] == eta], key=lambda r: r["youngs_modulus"])
                E = [r["youngs_modulus"] for r in rr]
                ax.plot(E, [r["measured_dt"] * 1e3 for r in rr], "-o", color=f"C{k}", ms=3,
                        label=f"eta {eta:g} Pa s measured")
                ax.plot(E, [r["estimated_dt"] * 1e3 for r in rr], "--", color=f"C{k}",
                        label=f"eta {eta:g} estimate")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel("Young's modulus E (Pa)")
            ax.set_title(name)
            ax.grid(alpha=0.3, which="both")
        np.atleast_1d(axes)[0].set_ylabel("largest stable step (ms)")
        np.atleast_1d(axes)[0].legend(fontsize=6.5)
        fig.suptitle(st.get("title", "stability map"), fontsize=9)
        fig.tight_layout()
        fig.savefig(os.path.join(IMG_DIR, "validation_stability.png"), dpi=110)
        plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--indent", required=True)
    ap.add_argument("--stability")
    ap.add_argument("--work", default=os.path.join(ROOT, "build-val", "validation-work"))
    ap.add_argument("--only", default="main,volume,sweep,stability")
    a = ap.parse_args()
    R = Runner(os.path.abspath(a.indent), a.work)
    os.makedirs(RES_DIR, exist_ok=True)
    res_path = os.path.join(RES_DIR, "summary.json")
    res = json.load(open(res_path)) if os.path.exists(res_path) else {}
    for study in a.only.split(","):
        print(f"== {study}", flush=True)
        if study == "main":
            res["main"] = study_main(R)
        elif study == "volume":
            res["volume"] = study_volume(R)
        elif study == "sweep":
            res["sweep"] = study_sweep(R)
        elif study == "stability" and a.stability:
            res["stability"] = study_stability(R, os.path.abspath(a.stability))
        json.dump(res, open(res_path, "w"), indent=1)
    if "main" in res:  # the stored calibration the fast ctest uses
        row = next(r for r in res["main"]["rows"] if r["radius_mm"] == 2.0)
        json.dump({"radius_mm": 2.0, "factor": row["factor"], "compression": row["compression"],
                   "punch": row["punch"], "reference_n": REF_N},
                  open(os.path.join(REF_DIR, "calibration.json"), "w"), indent=1)
    tables(res)
    charts(R, res)



def tables(res):
    """Markdown tables of the results (validation/results/tables.md, quoted in docs/validation.md)."""
    out = []
    if "main" in res:
        out.append("| r (mm) | spheres | links | punch spheres | factor | compression: max dd (mm) / RMS (N) | punch predicted: max dd (mm) / RMS (N) | punch covered | step (us) |")
        out.append("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        for r in res["main"]["rows"]:
            out.append(f"| {r['radius_mm']:g} | {r['spheres']} | {r['links']} | {r['punch_spheres']} | "
                       f"{r['factor']:.3f} | {r['compression']['max_disp_diff_mm']:.3f} / "
                       f"{r['compression']['rms_force_N']:.3f} | {r['punch']['max_disp_diff_mm']:.3f} / "
                       f"{r['punch']['rms_force_N']:.4f} | {100 * r['punch']['covered']:.0f} % | "
                       f"{r['step_us']:.0f} |")
        out.append("")
        out.append("Uncalibrated (factor 1): " + ", ".join(
            f"r {r['radius_mm']:g}: compression {r['compression_raw']['max_disp_diff_mm']:.2f} mm, "
            f"punch {r['punch_raw']['max_disp_diff_mm']:.2f} mm" for r in res["main"]["rows"]))
        out.append("")
        out.append("Checks: " + json.dumps(res["main"]["checks"]))
        out.append("")
    if "volume" in res:
        out.append("| nu | volume term | kappa (Pa) | dt (us) | factor | compression: max dd (mm) / RMS (N) | punch predicted: max dd (mm) / RMS (N) | step (us) | of which volume term (us) |")
        out.append("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        for r in res["volume"]["rows"]:
            out.append(f"| {r['nu']} | {'yes' if r['volume_term'] else 'no'} | {r['kappa_Pa']:.0f} | "
                       f"{r['dt'] * 1e6:.1f} | {r['factor']:.3f} | "
                       f"{r['compression']['max_disp_diff_mm']:.3f} / {r['compression']['rms_force_N']:.3f} | "
                       f"{r['punch']['max_disp_diff_mm']:.3f} / {r['punch']['rms_force_N']:.4f} | "
                       f"{r['step_us']:.0f} | {r['volume_us']:.0f} |")
        out.append("")
    if "sweep" in res:
        out.append("| filling | spheres | integrator | dt (us) | cost per simulated ms (ms) | factor | punch max dd (mm) |")
        out.append("| --- | --- | --- | --- | --- | --- | --- |")
        for r in res["sweep"]["rows"]:
            fill = (f"tetrahedral r {r['radius_mm']:g}" if r["filling"] == "tetrahedral"
                    else f"grid {r['spacing_mm']:g} mm")
            err = f"{r['punch']['max_disp_diff_mm']:.3f}" if r["ok"] else "diverged"
            fac = f"{r['factor']:.3f}" if r["ok"] else "-"
            out.append(f"| {fill} | {r['spheres']} | {r['integrator']} | {r['dt'] * 1e6:.1f} | "
                       f"{r['us_per_sim_ms'] / 1e3:.3f} | {fac} | {err} |")
        out.append("")
    if "stability" in res:
        out.append("| integrator | E (Pa) | eta (Pa s) | estimated dt (us) | measured dt (us) | measured / estimated |")
        out.append("| --- | --- | --- | --- | --- | --- |")
        for r in res["stability"]["rows"]:
            ratio = r["measured_dt"] / r["estimated_dt"] if r["estimated_dt"] > 0 else float("nan")
            out.append(f"| {r['integrator']} | {r['youngs_modulus']:g} | {r['viscosity']:g} | "
                       f"{r['estimated_dt'] * 1e6:.2f} | {r['measured_dt'] * 1e6:.2f} | {ratio:.2f} |")
    with open(os.path.join(RES_DIR, "tables.md"), "w") as f:
        f.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
