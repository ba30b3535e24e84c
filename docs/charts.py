#!/usr/bin/python3
"""Draws the charts of docs/benchmarks.md from the measurements in docs/data.

    /usr/bin/python3 docs/charts.py        (tools/dev.sh charts measures, then calls this)

Reads  docs/data/bench_force_model.json, docs/data/bench_integrators.json (Google Benchmark JSON)
       docs/data/integrator_accuracy.csv, docs/data/frame_accuracy.csv (if present)
       docs/data/model_step.jsonl (bench_model_step --json lines, one per model, law and threads)
       docs/data/model_step_nu.jsonl (bench_model_step --json --nu lines: the continuum law's
       cost against Poisson's ratio)
       docs/data/preconditioners.jsonl (bench_model_step --preconditioners lines, and --tolerance 1
       runs: the step without its solve)
Writes docs/img/force_per_link.png, docs/img/step_cost.png, docs/img/integrator_speed_accuracy.png,
       docs/img/frame_speed_accuracy.png, docs/img/scale_step_time.png, docs/img/model_step_time.png,
       docs/img/continuum_cost_nu.png, docs/img/preconditioner_step.png
"""
import csv
import json
import os
import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "data")
IMG = os.path.join(HERE, "img")
COLORS = {"improved_euler": "tab:orange", "heun": "tab:red", "symplectic_euler": "tab:blue",
          "implicit_euler": "tab:green"}


def load(name):
    with open(os.path.join(DATA, name)) as f:
        return json.load(f)


def per_link(b):
    return b["per_link"] * 1e9  # the counter is seconds per link


def force_chart():
    data = load("bench_force_model.json")
    series = {}
    for b in data["benchmarks"]:
        m = re.match(r"BM_ForceEvaluation<(\w+)>/cells:\d+/threads:(\d)/bilinear:(\d)"
                     r"(?:/simd:(\d))?", b["name"])
        if not m or b.get("run_type") == "aggregate":
            continue
        scalar, threads, bilinear, simd = m.groups()
        if bilinear != "1" or (scalar == "float" and simd == "1"):
            continue  # float has no SIMD kernel: its simd:1 rows are the scalar loop again
        kind = f"{scalar}, SIMD" if simd == "1" and scalar == "double" else f"{scalar}, scalar"
        series.setdefault((kind, threads), []).append((b["links"], per_link(b)))
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for (kind, threads), pts in sorted(series.items()):
        pts.sort()
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o",
                linestyle="-" if threads == "1" else "--",
                label=f"{kind}, {threads} thread{'s' if threads != '1' else ''}")
    ax.axhline(2.5, color="grey", linewidth=0.8)
    ax.text(1.2e3, 2.65, "target at 1e6 links, 2 cores: 2.5 ns", color="grey", fontsize=8)
    ax.set_xscale("log")
    ax.set_xlabel("links")
    ax.set_ylabel("force evaluation, ns per link")
    ax.set_ylim(bottom=0)
    ax.set_title("Voigt link forces (bilinear tissue), " + data["context"].get("host_name", ""))
    ax.legend(fontsize=7, loc="lower right", ncol=2)
    fig.tight_layout()
    fig.savefig(os.path.join(IMG, "force_per_link.png"), dpi=120)


def step_chart():
    data = load("bench_integrators.json")
    series = {}
    for b in data["benchmarks"]:
        m = re.match(r"BM_Step<double>/(\w+)/cells:\d+/threads:(\d)", b["name"])
        if not m or b.get("error_occurred"):
            continue
        name, threads = m.groups()
        series.setdefault((name, threads), []).append((b["links"], b["real_time"] * 1e-3))
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for (name, threads), pts in sorted(series.items()):
        pts.sort()
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", color=COLORS[name],
                linestyle="-" if threads == "1" else "--",
                label=f"{name}, {threads} thread{'s' if threads != '1' else ''}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("links")
    ax.set_ylabel("Simulation::step, microseconds")
    ax.set_title("One step with divergence checks (double)")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(os.path.join(IMG, "step_cost.png"), dpi=120)


def scale_chart():
    """Time per 1 ms implicit step against spheres, both laws, 1 and 2 threads; the real-time
    line (1 kHz) and the largest lattice under it marked."""
    data = load("bench_integrators.json")
    series = {}
    for b in data["benchmarks"]:
        m = re.match(r"BM_ScaleImplicitStep/cells:\d+/continuum:(\d)/threads:(\d)", b["name"])
        if not m or b.get("error_occurred"):
            continue
        law, threads = m.groups()
        series.setdefault((law, threads), []).append(
            (b["spheres"], b["real_time"], b["cg_iters"]))
    before = {}  # the same without the extrapolated warm start (one thread)
    for b in data["benchmarks"]:
        m = re.match(r"BM_ScaleImplicitStepNoExtrapolation/cells:\d+/continuum:(\d)/threads:1",
                     b["name"])
        if m and not b.get("error_occurred"):
            before.setdefault(m.group(1), []).append((b["spheres"], b["real_time"]))
    if not series:
        return
    fig, ax = plt.subplots(figsize=(6.6, 4.4))
    best = None
    for law, pts in sorted(before.items()):
        pts.sort()
        name = "continuum" if law == "1" else "links (the paper's)"
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="x", alpha=0.6, linestyle=":",
                color="tab:purple" if law == "1" else "tab:green",
                label=f"{name}, 1 thread, no extrapolated warm start")
    for (law, threads), pts in sorted(series.items()):
        pts.sort()
        name = "continuum" if law == "1" else "links (the paper's)"
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o",
                color="tab:purple" if law == "1" else "tab:green",
                linestyle="-" if threads == "1" else "--",
                label=f"{name}, {threads} thread{'s' if threads != '1' else ''}")
        for p in pts:
            if p[1] <= 1000 and (best is None or p[0] > best[0]):
                best = (p[0], p[1], name, threads)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(100, None)
    ax.axhline(1000, color="black", linewidth=0.8)
    ax.text(3000, 800, "real time at 1 kHz (1 ms per 1 ms step)", fontsize=7)
    if best:
        ax.annotate(f"largest in real time: {best[0]:.0f} spheres ({best[2]}, {best[3]} thr.)",
                    xy=(best[0], best[1]), xytext=(best[0] * 1.15, best[1] * 0.4), fontsize=7,
                    arrowprops={"arrowstyle": "->", "linewidth": 0.7})
    ax.set_xlabel("spheres (cube lattice, 5 mm)")
    ax.set_ylabel("one 1 ms implicit Euler step, microseconds")
    ax.set_title("Implicit step against model size (block-Jacobi CG)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(IMG, "scale_step_time.png"), dpi=120)


def model_step_chart():
    """Time per 1 ms implicit step of real models (a probe pressing) against spheres: mean and
    p99, both laws, 1 and 2 threads; the 1 kHz budget and the scale issue's 400 us target."""
    path = os.path.join(DATA, "model_step.jsonl")
    if not os.path.exists(path):
        return
    rows = [json.loads(line) for line in open(path) if line.strip()]
    fig, ax = plt.subplots(figsize=(7.0, 6.2))
    series = {}
    for r in rows:
        if r["diverged"]:
            continue
        # 0: today's defaults; 1: without the reuse of the energy check's force evaluation;
        # 2: the previous session's step (2026-11-26, its defaults), kept for the comparison.
        variant = (2 if r.get("session") == "2026-11-26" else
                   1 if not r.get("reuse_end_forces", True) else 0)
        series.setdefault((r["law"], r["threads"], variant), []).append(r)
    labels = {1: "without reusing the check's forces", 2: "on 2026-11-26"}
    for (law, threads, variant), pts in sorted(series.items()):
        pts.sort(key=lambda r: r["spheres"])
        style = {"color": "tab:purple" if law == "continuum" else "tab:green",
                 "linestyle": "-" if threads == 1 else "--", "marker": "o"}
        name = f"{law}, {threads} thread{'s' if threads > 1 else ''}"
        if variant:  # mean only
            style.update(linestyle=":" if variant == 1 else (0, (1, 4)),
                         marker="x" if variant == 1 else "+")
            ax.plot([r["spheres"] for r in pts], [r["mean_us"] for r in pts], alpha=0.7,
                    label=f"{name}, {labels[variant]}: mean", **style)
            continue
        ax.plot([r["spheres"] for r in pts], [r["mean_us"] for r in pts],
                label=f"{name}: mean", **style)
        ax.plot([r["spheres"] for r in pts], [r["p99_us"] for r in pts], alpha=0.35,
                label=f"{name}: p99", **style)
    seen = set()
    for r in rows:
        if (r["model"] not in seen and r["law"] == "links" and r["threads"] == 1
                and "session" not in r):
            seen.add(r["model"])
            ax.annotate(r["model"].split(" (")[0], xy=(r["spheres"], r["mean_us"]),
                        xytext=(-20, -18), textcoords="offset points", fontsize=7)
    ax.axhline(1000, color="black", linewidth=0.8)
    ax.text(700, 1050, "1 kHz budget", fontsize=7)
    ax.axhline(400, color="black", linewidth=0.6, linestyle=":")
    ax.text(700, 420, "scale issue's pelvis target (400 us)", fontsize=7)
    ax.plot([660, 730], [300, 300], color="tab:purple", linewidth=0.8)
    ax.text(740, 290, "fidelity issue's uterus continuum target (300 us)", fontsize=7)
    ax.set_yscale("log")
    ax.set_xlim(600, 2050)
    ax.set_xlabel("spheres")
    ax.set_ylabel("one 1 ms implicit Euler step with a probe, microseconds")
    ax.set_title("Real models: step time (block-Jacobi CG to 1e-3, drag 5/s)")
    ax.legend(fontsize=6, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.12))
    fig.tight_layout()
    fig.savefig(os.path.join(IMG, "model_step_time.png"), dpi=120)


def nu_chart():
    """The continuum law's step time and CG iterations against Poisson's ratio (real models, one
    thread), the link law (which has no Poisson's ratio) as a level line."""
    path = os.path.join(DATA, "model_step_nu.jsonl")
    if not os.path.exists(path):
        return
    rows = [json.loads(line) for line in open(path) if line.strip()]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10.0, 4.2))
    models = list(dict.fromkeys(r["model"] for r in rows))
    for model, color in zip(models, ["tab:purple", "tab:brown", "tab:olive"]):
        pts = sorted((r for r in rows if r["model"] == model and r["law"] == "continuum"),
                     key=lambda r: r["nu"])
        nus = [r["nu"] for r in pts]
        ax.plot(nus, [r["mean_us"] for r in pts], "o-", color=color, label=f"{model}: continuum, mean")
        ax.plot(nus, [r["p99_us"] for r in pts], "o-", color=color, alpha=0.35,
                label=f"{model}: continuum, p99")
        bx.plot(nus, [r["cg_iterations"] for r in pts], "o-", color=color, label=f"{model}: continuum")
        for r in rows:
            if r["model"] == model and r["law"] == "links":
                ax.axhline(r["mean_us"], color=color, linestyle="--", linewidth=0.9,
                           label=f"{model}: links (no nu), mean")
                bx.axhline(r["cg_iterations"], color=color, linestyle="--", linewidth=0.9,
                           label=f"{model}: links")
    ax.axhline(1000, color="black", linewidth=0.8)
    ax.text(0.3, 1060, "1 kHz budget", fontsize=7)
    ax.axhline(300, color="black", linewidth=0.6, linestyle=":")
    ax.text(0.3, 315, "uterus continuum target (300 us)", fontsize=7)
    ax.set_yscale("log")
    for a in (ax, bx):
        a.set_xlabel("Poisson's ratio nu (the continuum law's)")
    ax.set_ylabel("one 1 ms implicit step with a probe, microseconds")
    bx.set_ylabel("CG iterations per step (block-Jacobi, to 1e-3)")
    ax.set_title("Step time against nu, one thread")
    bx.set_title("CG iterations against nu")
    ax.legend(fontsize=6)
    bx.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(os.path.join(IMG, "continuum_cost_nu.png"), dpi=120)


def preconditioner_chart():
    """The scale issue's sparse-Cholesky preconditioner against the block-Jacobi step, per model
    and law (bench_model_step --preconditioners): the block-Jacobi step as measured, and estimates
    of a step preconditioned by a CHOLMOD factor (on OpenBLAS): the step without its solve
    (--tolerance 1) plus one factor application for the right-hand side and one per PCG iteration
    (from zero, to the step's 1e-3), for a factor at this state (1 iteration: a lower bound) and
    for one 10 steps old, with the probe held ("held") and while the tissue still moves after the
    press ("pressing")."""
    path = os.path.join(DATA, "preconditioners.jsonl")
    if not os.path.exists(path):
        return
    rows = [json.loads(line) for line in open(path) if line.strip()]
    study = [r for r in rows if "preconditioners_to" in r]
    bare = {(r["model"], r["law"]): r["mean_us"] for r in rows if r.get("tolerance") == 1}
    keys = [k for k in dict.fromkeys((r["model"], r["law"]) for r in study) if k in bare]
    if not keys:
        return

    def pick(k, run, phase, tol=None):
        return [r for r in study if (r["model"], r["law"]) == k and r["run"].startswith(run) and
                r["phase"] == phase and (tol is None or r["preconditioners_to"] == tol)]

    # Timings from the OpenBLAS run (the faster of its two lines: the machine's noise), iterations
    # to 1e-3 from the held and pressing lines; the block-Jacobi step: the faster of the runs on an
    # idle machine.
    def apply_us(k):
        return min(r["cholmod_apply_us"] for r in pick(k, "openblas", "held"))

    def step_us(k):
        return min(r["step_mean_us"] for r in study if (r["model"], r["law"]) == k and
                   not r["run"].startswith("phases"))

    def lag10(k, phase):
        return pick(k, "openblas" if phase == "held" else "phases", phase, 1e-3)[0]["it_cholesky_lag10"]

    series = [("block-Jacobi step (measured)", "tab:green", lambda k: step_us(k)),
              ("Cholesky at this state (lower bound)", "tab:blue", lambda k: bare[k] + 2 * apply_us(k)),
              ("Cholesky 10 steps old, probe held (estimate)", "tab:purple",
               lambda k: bare[k] + (lag10(k, "held") + 1) * apply_us(k)),
              ("Cholesky 10 steps old, tissue moving (estimate)", "tab:red",
               lambda k: bare[k] + (lag10(k, "pressing") + 1) * apply_us(k))]
    fig, ax = plt.subplots(figsize=(9.0, 4.6))
    width = 0.2
    for j, (label, color, f) in enumerate(series):
        ax.bar([i + (j - 1.5) * width for i in range(len(keys))], [f(k) for k in keys], width,
               color=color, label=label)
    factor = {k: min(r["cholmod_factor_us"] for r in pick(k, "openblas", "held")) for k in keys}
    ax.set_xticks(range(len(keys)))
    ax.set_xticklabels([f"{m.replace('.fsm', '')}\n{law}\n(factor {factor[(m, law)] / 1e3:.0f} ms)"
                        for m, law in keys], fontsize=7)
    ax.axhline(1000, color="black", linewidth=0.8)
    ax.text(-0.45, 1060, "1 kHz budget", fontsize=7)
    ax.set_ylabel("one 1 ms implicit step, microseconds (one core)")
    ax.set_title("Sparse Cholesky (CHOLMOD, OpenBLAS) as CG's preconditioner against block-Jacobi")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(IMG, "preconditioner_step.png"), dpi=120)


def accuracy_chart():
    rows = list(csv.DictReader(open(os.path.join(DATA, "integrator_accuracy.csv"))))
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for name in COLORS:
        pts = [(float(r["cost_s_per_s"]), float(r["error_m"]) * 1e6, float(r["dt_s"]))
               for r in rows if r["integrator"] == name and r["status"] == "ok"]
        if not pts:
            continue
        ax.plot([p[0] for p in pts], [max(p[1], 1e-6) for p in pts], marker="o",
                color=COLORS[name], label=name)
        for c, e, dt in pts:
            ax.annotate(f"{dt * 1e3:g}", (c, max(e, 1e-6)), fontsize=6, xytext=(3, 2),
                        textcoords="offset points")
    ax.axvline(1.0, color="grey", linewidth=0.8)
    ax.text(1.05, 0.97, "real time", color="grey", fontsize=8, va="top",
            transform=ax.get_xaxis_transform())
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall seconds per simulated second (1 thread)")
    ax.set_ylabel("RMS position error vs Heun at 1 us (um)")
    ax.set_title("Speed against accuracy: 726-sphere tissue sample, labels = dt (ms)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(IMG, "integrator_speed_accuracy.png"), dpi=120)


def frame_chart():
    """Whole-frame rate against accuracy over CG tolerances, sleeping off/on (frame_accuracy)."""
    path = os.path.join(DATA, "frame_accuracy.csv")
    if not os.path.exists(path):
        return
    with open(path) as f:
        rows = list(csv.DictReader(f))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for sleep, colour, label in (("0", "tab:green", "sleeping off"), ("1", "tab:purple", "sleeping on")):
        pts = [r for r in rows if r["sleep"] == sleep]
        x = [max(float(r["surface_rms_um"]), 1e-4) for r in pts]
        y = [float(r["frame_hz"]) for r in pts]
        ax.plot(x, y, "o-", color=colour, label=label)
        if sleep == "0":
            for r, xi, yi in zip(pts, x, y):
                ax.annotate("tol %s" % r["tolerance"], (xi, yi), textcoords="offset points", xytext=(4, 4),
                            fontsize=7)
    ax.axhline(500, color="tab:red", ls="--", lw=1, label="target 500 Hz")
    ax.axhspan(40, 60, color="tab:gray", alpha=0.3, label="paper 40-60 Hz")
    ax.set_xscale("log")
    ax.set_xlabel("surface RMS difference from a CG 1e-9 run after 3 s (um)")
    ax.set_ylabel("whole-frame rate (Hz)")
    ax.set_title("Uterus whole frame: 17 implicit steps + contacts + skinning")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(IMG, "frame_speed_accuracy.png"), dpi=120)


if __name__ == "__main__":
    os.makedirs(IMG, exist_ok=True)
    force_chart()
    step_chart()
    scale_chart()
    model_step_chart()
    nu_chart()
    preconditioner_chart()
    accuracy_chart()
    frame_chart()
    print("wrote", ", ".join(sorted(os.listdir(IMG))))
