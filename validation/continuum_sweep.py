#!/usr/bin/python3
"""Both force laws, uncalibrated, against the converged CalculiX reference, at several resolutions,
with same-mesh finite elements beside them.

    /usr/bin/python3 validation/continuum_sweep.py --indent build/validation/fsm-indent \
        --build build/src/builder/fsm-build [--radii 2.5 2 1.5 1.25] [--work /tmp/sweep] \
        [--no-fem] [--reuse]

For each sphere radius (the builder's isotropic metric on the 20 x 20 x 10 mm box, sharp edges
protected) it runs fsm-indent at 150 mm/min for each case and law, and compares with
reference/converged_<case>_nu<nu>.csv: the largest displacement difference at equal force (the
paper's metric), the RMS force error, and the largest relative force error from 0.5 to 2.5 mm.

- cases: bonded compression, the bonded 4 x 4 mm punch and the rigid 5 mm ball through contact,
  each at nu = 0.49 and 0.45; the rigid flat-ended cylinder with a rounded rim (R 3 mm, rim 1 mm)
  where its converged reference exists (a study without one is skipped);
- laws: the paper's link network (it has no Poisson's ratio: one run per case, scored against
  each nu's reference) and the continuum law at each nu; for the ball, also the continuum law
  with the face contact (ContactOptions::face_contact);
- --studies case:nu,... reruns only those studies and replaces their rows in the results;
- same-mesh FEM (unless --no-fem; bonded cases only): CalculiX C3D4 and C3D10 (the same
  tetrahedra, straight mid-side nodes) on the exact mesh fsm-build makes from the scene
  (validation/fem.py). C3D4 against the converged reference is the discretisation error of
  linear tetrahedra on this mesh (with their volumetric locking); C3D10 that of the same mesh
  with a quadratic field; the continuum law against C3D4 is what its nodal pressure changes.

Writes validation/results/continuum_sweep.json and three charts in docs/img: error against
spacing (log-log, with the observed order), median step time against error, and the
force-displacement curves at one radius.
"""
import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import axisym  # noqa: E402
import fem  # noqa: E402
import scenes  # noqa: E402
import validate  # noqa: E402

# (case, nu) pairs scored.
BOX_STUDIES = [("compression", 0.49), ("compression", 0.45), ("punch", 0.49), ("punch", 0.45),
               ("sphere", 0.49), ("sphere", 0.45)]
# The indenters on the cylindrical specimen (validation/axisym.py: its axisymmetric reference
# converges for the flat-ended cylinders too).
DISC_STUDIES = [(c, nu) for c in axisym.CASES for nu in (0.49, 0.45)]
STUDIES = BOX_STUDIES + [("rounded_cylinder", 0.49), ("rounded_cylinder", 0.45)] + DISC_STUDIES
# Smooth indenters through contact: scored also by the largest force error from 0.5 to 2.5 mm.
CONTACT = ("sphere", "rounded_cylinder") + axisym.CASES
# The laws run per case: the ball also with the face contact (fsm-indent --contact faces); the
# continuum law also with smoothed deviatoric strains ("continuum/node": fsm-indent --smoothing
# node, ForceModel::Options::strain_smoothing, default element share).
SMOOTHED = ("continuum/face", "continuum/node")
LAWS = {"compression": ("links", "continuum") + SMOOTHED, "punch": ("links", "continuum") + SMOOTHED,
        "sphere": ("links", "continuum", "continuum+faces") + SMOOTHED,
        "rounded_cylinder": ("links", "continuum", "continuum+faces") + SMOOTHED}
LAWS.update({c: ("links", "continuum", "continuum+faces") + SMOOTHED for c in axisym.CASES})


def indent_flags(law):
    """fsm-indent flags of a law name: base[/smoothing][+faces]."""
    base, _, contact = law.partition("+")
    base, _, smoothing = base.partition("/")
    return ["--law", base, "--contact", "faces" if contact == "faces" else "vertices",
            "--smoothing", smoothing or "element"]
BONDED = ("compression", "punch")


def indent_run(a, scene, case, law, nu, r):
    """(curve path, fsm-indent's JSON summary) of one run at 150 mm/min in a.work (the links have
    no Poisson's ratio: one run, tagged without it); with a.reuse, a run already there is read."""
    return indent_tagged(a, scene, case, law, nu,
                         f"{case}_{law.replace('+', '_').replace('/', '_')}_r{r:g}" +
                         (f"_nu{nu:g}" if law != "links" else ""))


def indent_tagged(a, scene, case, law, nu, tag):
    """indent_run() under a given name: a.work/<tag>.csv and .json."""
    curve, summary = (os.path.join(a.work, tag + x) for x in (".csv", ".json"))
    if not (a.reuse and os.path.exists(curve) and os.path.exists(summary)):
        p = subprocess.run([a.indent, scene, "--case", axisym.indenter_case(case), *indent_flags(law),
                            "--nu", str(nu),
                            "--speed", "150", "--out", curve], capture_output=True, text=True)
        if p.returncode not in (0, 3):
            sys.exit(f"fsm-indent failed: {p.stderr}")
        with open(summary, "w") as f:
            f.write(p.stdout)
    with open(summary) as f:
        return curve, json.load(f)


def graded_reference(nu):
    """The compression reference of the mesh family graded toward the bonded edges
    (reference/converged_compression_graded_nu<nu>.csv: make_reference.py), or None. It ends
    where fewer than two of its meshes converged (the side faces fold at the bonded corners)."""
    path = os.path.join(validate.REF_DIR, f"converged_compression_graded_nu{nu:g}.csv")
    return validate.converged_reference("compression_graded", nu) if os.path.exists(path) else None


def parse_studies(text):
    """[(case, nu)] of --studies' "case:nu,case:nu"."""
    return [(c, float(n)) for c, n in (x.split(":") for x in text.split(","))]


def score(d, F, case, nu):
    dr, Fr = validate.converged_reference(case, nu)
    m = validate.metrics(d, F, dr, Fr)
    out = {"max_disp_diff_mm": m["max_disp_diff_mm"], "rms_force_N": m["rms_force_N"],
           "covered": m["covered"],
           "max_rel_force_error_0p5_2p5": validate.max_force_error(d, F, dr, Fr),
           "force_1p25_N": float(np.interp(1.25, d, F)), "force_2p5_N": float(F[-1]),
           "reference_1p25_N": float(np.interp(1.25, dr, Fr)),
           "reference_2p5_N": float(Fr[-1])}
    g = graded_reference(nu) if case == "compression" else None
    if g is not None:
        # Against the graded family's reference over its range, and against the uniform family's
        # over the same range (the same metric: what the sharper reference changes).
        dg, Fg = g
        keep = dr <= dg[-1] + 1e-9
        mg = validate.metrics(d, F, dg, Fg)
        mu = validate.metrics(d, F, dr[keep], Fr[keep])
        out.update({"graded_to_mm": float(dg[-1]), "graded_max_disp_diff_mm": mg["max_disp_diff_mm"],
                    "graded_rms_force_N": mg["rms_force_N"],
                    "uniform_same_range_max_disp_diff_mm": mu["max_disp_diff_mm"],
                    "graded_reference_1p25_N": float(np.interp(1.25, dg, Fg))})
    return out


def write_curve(path, d, F):
    with open(path, "w") as f:
        f.write("displacement_mm,force_N\n")
        for a, b in zip(d, F):
            f.write(f"{a:.6f},{b:.8g}\n")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--indent", required=True)
    ap.add_argument("--build", default=os.path.join(ROOT, "build", "src", "builder", "fsm-build"))
    ap.add_argument("--radii", type=float, nargs="+", default=[2.5, 2.0, 1.5, 1.25])
    ap.add_argument("--work", default="/tmp/fsm-continuum-sweep")
    ap.add_argument("--no-fem", action="store_true", help="skip the same-mesh CalculiX runs")
    ap.add_argument("--reuse", action="store_true", help="keep curves already in --work")
    ap.add_argument("--ccx", default="/usr/bin/ccx")
    ap.add_argument("--studies", default=None,
                    help="only these studies, e.g. sphere:0.45,sphere:0.49; their rows replace "
                         "those in results/continuum_sweep.json, the others are kept")
    ap.add_argument("--laws", default=None,
                    help="only these laws, e.g. continuum/node,continuum/face; their rows replace "
                         "those in results/continuum_sweep.json, the others are kept")
    ap.add_argument("--rescore", action="store_true",
                    help="score every stored curve again against the reference as it is now "
                         "(after validation/make_reference.py changed it), then redraw")
    ap.add_argument("--charts-only", action="store_true",
                    help="redraw the charts from results/continuum_sweep.json")
    ap.add_argument("--indicative", default=None, metavar="CASE:N",
                    help="a contact case without a converged reference (rounded_cylinder:5): run "
                         "every law at --radii (or reuse --work's curves) and write "
                         "results/<case>_runs.md against CalculiX mesh N, not converged")
    a = ap.parse_args()
    if a.indicative:
        case, n = a.indicative.split(":")
        indicative(a, case, int(n))
        return
    if a.rescore:
        result = os.path.join(HERE, "results", "continuum_sweep.json")
        with open(result) as f:
            data = json.load(f)
        # With --studies: only those studies' rows (their curves must still exist).
        only = set(parse_studies(a.studies)) if a.studies else None
        for x in data["runs"]:
            if "failed" in x or (only is not None and (x["case"], x["nu"]) not in only):
                continue
            if not os.path.exists(x["curve"]):
                sys.exit(f"--rescore: {x['curve']} is gone; rerun that study or pass --studies")
            x.update(score(*validate.read_curve(x["curve"]), x["case"], x["nu"]))
        data["command"] += "; then validation/continuum_sweep.py --rescore" + (
            f" --studies {a.studies}" if a.studies else "")
        data["rescored"] = time.strftime("%Y-%m-%d")
        with open(result, "w") as f:
            json.dump(data, f, indent=1)
        a.charts_only = True
    if a.charts_only:
        with open(os.path.join(HERE, "results", "continuum_sweep.json")) as f:
            rows = json.load(f)["runs"]
        charts(rows)
        tables(rows)
        return
    studies = STUDIES
    if a.studies:
        studies = parse_studies(a.studies)
        for st in studies:
            if st not in STUDIES:
                sys.exit(f"unknown study {st}")
    # A study without a converged reference (make_reference.py did not get one: the rounded
    # cylinder, docs/validation.md) cannot be scored: skipped, and said so.
    missing = [st for st in studies if not os.path.exists(
        os.path.join(validate.REF_DIR, f"converged_{st[0]}_nu{st[1]:g}.csv"))]
    for case, nu in missing:
        print(f"no converged reference for {case} at nu = {nu:g}: not run", file=sys.stderr)
    studies = [st for st in studies if st not in missing]
    os.makedirs(a.work, exist_ok=True)
    box = os.path.join(a.work, "box.off")
    scenes.write_box_off(box)
    disc = os.path.join(a.work, "disc.off")
    scenes.write_disc_off(disc)
    rows = []

    def record(row):
        rows.append(row)
        print(json.dumps(row), flush=True)

    for r in a.radii:
        scene = os.path.join(a.work, f"r{r:g}.json")
        scenes.write_scene(scene, box, "tetrahedral", r, scenes.LINEAR)
        disc_scene = os.path.join(a.work, f"disc_r{r:g}.json")
        scenes.write_scene(disc_scene, disc, "tetrahedral", r, scenes.LINEAR)
        runs = {}  # (case, law, nu) -> (curve path, fsm-indent summary)
        for case, nu in studies:
            for law in LAWS[case]:
                if a.laws and law not in a.laws.split(","):
                    continue
                key_nu = nu if law != "links" else None
                if (case, law, key_nu) in runs:
                    continue
                runs[(case, law, key_nu)] = indent_run(
                    a, disc_scene if case.startswith("disc_") else scene, case, law, nu, r)
        for case, nu in studies:
            for law in LAWS[case]:
                if (case, law, nu if law != "links" else None) not in runs:
                    continue
                out, s = runs[(case, law, nu if law != "links" else None)]
                d, F = validate.read_curve(out)
                record({"radius_mm": r, "case": case, "nu": nu, "law": law,
                        "spheres": s["spheres"], "tetrahedra": s.get("tetrahedra"),
                        **score(d, F, case, nu), "median_step_us": s["median_step_us"],
                        "mean_iterations": s["mean_iterations"], "diverged": s["diverged"],
                        "inverted_steps": s["inverted_steps"],
                        "max_penetration_m": s["max_penetration_m"],
                        "max_face_penetration_m": s.get("max_face_penetration_m"), "curve": out})
        if a.no_fem:
            continue
        model = os.path.join(a.work, f"r{r:g}.fsm")
        subprocess.run([a.build, scene, "-o", model, "-q"], check=True, capture_output=True)
        P, T = fem.load_fsm_tets(model)
        for case, nu in studies:
            if case not in BONDED:
                continue
            for order, element in ((1, "C3D4"), (2, "C3D10")):
                out = os.path.join(a.work, f"{case}_{element}_r{r:g}_nu{nu:g}.csv")
                seconds = None
                if not (a.reuse and os.path.exists(out)):
                    t0 = time.time()
                    try:
                        d, F = fem.run_tet_mesh(os.path.join(a.work, "ccx"), case, P, T, nu,
                                                ccx=a.ccx, order=order,
                                                job=f"{element}_{case}_r{r:g}_nu{nu:g}".replace(
                                                    ".", "p"))
                    except (RuntimeError, ValueError) as e:
                        record({"radius_mm": r, "case": case, "nu": nu, "law": element,
                                "spheres": len(P), "failed": str(e)[:300]})
                        continue
                    seconds = round(time.time() - t0, 1)
                    write_curve(out, d, F)
                d, F = validate.read_curve(out)
                record({"radius_mm": r, "case": case, "nu": nu, "law": element,
                        "spheres": len(P), "tetrahedra": len(T), **score(d, F, case, nu),
                        "ccx_seconds": seconds, "curve": out})
    result = os.path.join(HERE, "results", "continuum_sweep.json")
    command = "validation/continuum_sweep.py --radii " + " ".join(f"{r:g}" for r in a.radii) + (
        " --no-fem" if a.no_fem else "") + (f" --studies {a.studies}" if a.studies else "")
    if a.laws:
        command += f" --laws {a.laws}"
    if (a.studies or a.laws) and os.path.exists(result):  # replace the rows of these studies, keep the rest
        with open(result) as f:
            old = json.load(f)
        kept = [x for x in old["runs"] if (x["case"], x["nu"]) not in studies or
                x["radius_mm"] not in a.radii or (a.laws and x["law"] not in a.laws.split(","))]
        rows = kept + rows
        command = old["command"] + "; then " + command
    with open(result, "w") as f:
        json.dump({"command": command, "date": time.strftime("%Y-%m-%d"), "runs": rows}, f,
                  indent=1)
    charts(rows)
    tables(rows)


def indicative(a, case, n):
    """results/<case>_runs.md: every law of LAWS[case] at each radius (and its contact's depth
    inside the tool, cost, iterations, diverged steps) against the CalculiX curve of mesh n
    (reference/<case>_nu<nu>_n<n>.csv), which is not a converged reference."""
    os.makedirs(a.work, exist_ok=True)
    box = os.path.join(a.work, "box.off")
    scenes.write_box_off(box)
    names = {law: STYLE[law][2] for law in LAWS[case]}
    out = [f"# {case}, every run (written by validation/continuum_sweep.py --indicative {case}:{n})",
           "", f"fsm-indent at 150 mm/min on the sweep's boxes; the force against CalculiX mesh n = {n} "
           f"(reference/{case}_nu<nu>_n{n}.csv), **not a converged reference** (on the ball, n = 5 "
           "was 1.4 % stiffer than the converged value at 2.5 mm). Generated "
           f"{time.strftime('%Y-%m-%d')}.", "",
           "| r (mm) | spheres | law | nu | F(1.25 mm), N | F(2.5 mm), N | deepest sphere centre "
           "inside the tool (mm) | median step (us) | CG it. | diverged steps |",
           "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in a.radii:
        scene = os.path.join(a.work, f"r{r:g}.json")
        scenes.write_scene(scene, box, "tetrahedral", r, scenes.LINEAR)
        for law in LAWS[case]:
            if a.laws and law not in a.laws.split(","):
                continue
            for nu in ((0.49,) if law == "links" else (0.49, 0.45)):
                curve, s = indent_run(a, scene, case, law, nu, r)
                d, F = validate.read_curve(curve)
                ref = np.loadtxt(os.path.join(validate.REF_DIR, f"{case}_nu{nu:g}_n{n}.csv"),
                                 delimiter=",", skiprows=1)
                f1, f2 = np.interp(1.25, d, F), F[-1]
                r1, r2 = np.interp(1.25, ref[:, 0], ref[:, 1]), ref[-1, 1]
                cell2 = (f"{f2:.4f} ({100 * (f2 / r2 - 1):+.0f} %)" if abs(f2) < 10 * r2
                         else f"{f2:.3g} (blown up)")
                out.append(f"| {r:g} | {s['spheres']} | {names[law]} | "
                           f"{'-' if law == 'links' else f'{nu:g}'} | "
                           f"{f1:.4f} ({100 * (f1 / r1 - 1):+.0f} %) | {cell2} | "
                           f"{1e3 * s['max_penetration_m']:.4f} | {s['median_step_us']:.0f} | "
                           f"{s['mean_iterations']:.0f} | {s['diverged']} |")
                print(out[-1], flush=True)
    with open(os.path.join(HERE, "results", f"{case}_runs.md"), "w") as f:
        f.write("\n".join(out) + "\n")


def law_table(here, cols, cell):
    """The markdown rows of a per-radius table: one row per radius (largest first), the nodes, and
    cell(run) for every law in cols ("-" where it has no run)."""
    out = ["| r (mm) | nodes | " + " | ".join(STYLE[c][2] for c in cols) + " |",
           "| --- | --- | " + " | ".join("---" for _ in cols) + " |"]
    for r in sorted({x["radius_mm"] for x in here}, reverse=True):
        at = {x["law"]: x for x in here if x["radius_mm"] == r}
        nodes = next((str(at[c]["spheres"]) for c in cols if c in at), "")
        out.append(f"| {r:g} | {nodes} | " + " | ".join(cell(at[c]) if c in at else "-"
                                                         for c in cols) + " |")
    return out


def tables(rows):
    """validation/results/continuum_tables.md: per study, the largest displacement difference
    (mm) of every law at every radius, with the force at 1.25 mm against the reference's and, for
    the ball, the largest relative force error from 0.5 to 2.5 mm."""
    ok = [x for x in rows if "failed" not in x]
    laws = [law for law in STYLE if any(x["law"] == law for x in ok)]
    out = ["# The continuum sweep's tables (written by validation/continuum_sweep.py)", ""]
    for case, nu in STUDIES:
        here = [x for x in ok if x["case"] == case and x["nu"] == nu]
        cols = [law for law in laws if any(x["law"] == law for x in here)]
        if not here:
            continue
        out += [f"**{case}, nu = {nu:g}** (largest displacement difference, mm; in brackets the "
                "force at 1.25 mm against the reference's" +
                ("; then the largest force error from 0.5 to 2.5 mm" if case in CONTACT else "")
                + ")", ""]

        def cell(x, case=case):
            rel = x["force_1p25_N"] / x["reference_1p25_N"] - 1
            text = f"{x['max_disp_diff_mm']:.3f} ({100 * rel:+.0f} %)"
            if case in CONTACT:
                text += f", {100 * x['max_rel_force_error_0p5_2p5']:.1f} %"
            return text
        out += law_table(here, cols, cell) + [""]
    # Compression against the graded family's reference (where it exists).
    graded = [x for x in ok if "graded_max_disp_diff_mm" in x]
    if graded:
        cols = [law for law in laws if any(x["law"] == law for x in graded)]
        out += ["**Compression against the reference of the mesh family graded toward the bonded "
                "edges** (largest displacement difference up to the depth that reference reaches, "
                "mm; in brackets the same against the uniform family's reference over the same range)",
                ""]
        for nu in sorted({x["nu"] for x in graded}, reverse=True):
            here = [x for x in graded if x["nu"] == nu]
            to = here[0]["graded_to_mm"]
            out += [f"nu = {nu:g}, to {to:g} mm:", ""] + law_table(
                here, cols, lambda x: f"{x['graded_max_disp_diff_mm']:.3f} "
                                      f"({x['uniform_same_range_max_disp_diff_mm']:.3f})") + [""]
    # The strain smoothings side by side at the two finest spacings.
    smooth = ("continuum", "continuum/face", "continuum/node")
    out += ["**The deviatoric strain per element, face-smoothed and node-smoothed** (largest "
            "displacement difference, mm; in brackets the force at 1.25 mm against the reference's; "
            "for the ball, then the largest force error from 0.5 to 2.5 mm)", "",
            "| case | nu | r (mm) | nodes | element | face | node |",
            "| --- | --- | --- | --- | --- | --- | --- |"]
    for case, nu in STUDIES:
        for r in (1.5, 1.25):
            here = {x["law"]: x for x in ok if x["case"] == case and x["nu"] == nu
                    and x["radius_mm"] == r and x["law"] in smooth}
            if len(here) < len(smooth):
                continue
            cells = []
            for law in smooth:
                x = here[law]
                rel = x["force_1p25_N"] / x["reference_1p25_N"] - 1
                cell = f"{x['max_disp_diff_mm']:.3f} ({100 * rel:+.0f} %)"
                if case in CONTACT:
                    cell += f", {100 * x['max_rel_force_error_0p5_2p5']:.1f} %"
                cells.append(cell)
            out.append(f"| {case} | {nu:g} | {r:g} | {here['continuum']['spheres']} | " +
                       " | ".join(cells) + " |")
    out.append("")
    with open(os.path.join(HERE, "results", "continuum_tables.md"), "w") as f:
        f.write("\n".join(out))


STYLE = {"links": ("o--", "tab:blue", "paper's link network"),
         "continuum": ("s-", "tab:red", "continuum law"),
         "continuum+faces": ("D-.", "tab:purple", "continuum law, face contact"),
         "continuum/face": ("<-", "tab:orange", "continuum law, face-smoothed strain"),
         "continuum/node": (">-", "tab:brown", "continuum law, node-smoothed strain"),
         "C3D4": ("^:", "tab:grey", "same-mesh C3D4 (CalculiX)"),
         "C3D10": ("v:", "tab:green", "same-mesh C3D10 (CalculiX)")}


def charts(rows):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    img = os.path.join(ROOT, "docs", "img")
    ok = [x for x in rows if "failed" not in x]
    from matplotlib.ticker import NullFormatter
    fig, axes = plt.subplots(2, 3, figsize=(13, 8))
    axes = axes.ravel()
    for ax, (case, nu) in zip(axes, BOX_STUDIES):
        for law, (style, colour, name) in STYLE.items():
            pts = [x for x in ok if x["case"] == case and x["nu"] == nu and x["law"] == law]
            if not pts:
                continue
            h = np.array([x["radius_mm"] for x in pts])
            e = np.array([max(x["max_disp_diff_mm"], 1e-4) for x in pts])
            label = name
            if len(h) >= 2:
                label += f" (order {np.polyfit(np.log(h), np.log(e), 1)[0]:.2f})"
            ax.loglog(h, e, style, color=colour, label=label)
        ax.axhline(0.05, color="black", lw=0.8, ls=":", label="target 0.05 mm")
        radii = sorted({x["radius_mm"] for x in ok if (x["case"], x["nu"]) == (case, nu)})
        ax.set_xticks(radii)
        ax.set_xticklabels([f"{r:g}" for r in radii])
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_title(f"{case}, nu = {nu:g}")
        ax.set_xlabel("sphere radius = element size (mm)")
        ax.set_ylabel("largest displacement difference (mm)")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=6)
    fig.suptitle("error against the converged reference, uncalibrated", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(img, "validation_error_vs_spacing.png"), dpi=100)
    plt.close(fig)

    # The indenters on the cylindrical specimen: the force error against spacing (the target is
    # on the force: within 5 % from 0.5 to 2.5 mm).
    disc = [x for x in ok if x["case"].startswith("disc_")]
    if disc:
        fig, axes = plt.subplots(2, 3, figsize=(13, 8))
        for col, case in enumerate(axisym.CASES):
            for row, nu in enumerate((0.49, 0.45)):
                ax = axes[row][col]
                for law, (style, colour, name) in STYLE.items():
                    pts = sorted((x for x in disc if x["case"] == case and x["nu"] == nu and
                                  x["law"] == law), key=lambda x: x["radius_mm"])
                    if not pts:
                        continue
                    # clipped at 300 %: the face contact's runs whose steps diverged
                    ax.loglog([x["radius_mm"] for x in pts],
                              [min(max(100 * x["max_rel_force_error_0p5_2p5"], 0.1), 300)
                               for x in pts], style, color=colour, label=name)
                if not any(x["case"] == case and x["nu"] == nu for x in disc):
                    ax.text(0.5, 0.5, "no converged reference\n(reference/README.md)",
                            ha="center", va="center", transform=ax.transAxes)
                    ax.set_xscale("log")
                ax.axhline(5, color="black", lw=0.8, ls=":", label="target 5 %")
                radii = sorted({x["radius_mm"] for x in disc})
                ax.set_xticks(radii)
                ax.set_xticklabels([f"{r:g}" for r in radii])
                ax.xaxis.set_minor_formatter(NullFormatter())
                ax.set_title(f"{case[5:]} on the cylindrical specimen, nu = {nu:g}", fontsize=9)
                ax.set_xlabel("sphere radius = element size (mm)")
                ax.set_ylabel("largest force error, 0.5-2.5 mm (%; clipped at 300)")
                ax.grid(alpha=0.3, which="both")
                ax.legend(fontsize=6)
        fig.suptitle("force error against the converged axisymmetric reference, uncalibrated",
                     fontsize=10)
        fig.tight_layout()
        fig.savefig(os.path.join(img, "validation_disc_force_error.png"), dpi=100)
        plt.close(fig)

    fig, ax = plt.subplots(figsize=(5.5, 4))
    for case, marker in (("compression", "o"), ("sphere", "s")):
        for law in ("links", "continuum", "continuum/node"):
            pts = [x for x in ok if x["case"] == case and x["law"] == law and x["nu"] == 0.49]
            ax.loglog([x["median_step_us"] for x in pts], [x["max_disp_diff_mm"] for x in pts],
                      marker=marker, color=STYLE[law][1], ls="-", label=f"{case}, {law}")
    ax.axhline(0.05, color="grey", lw=0.8, ls=":")
    ax.axvline(1000, color="grey", lw=0.8, ls=":")
    ax.set_xlabel("median implicit step, 1 ms (us, one core)")
    ax.set_ylabel("largest displacement difference (mm)")
    ax.set_title("speed against accuracy, uncalibrated (nu = 0.49)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(img, "validation_speed_accuracy_laws.png"), dpi=110)
    plt.close(fig)

    # Force against displacement at the radius nearest 1.5 mm, both nu, compression and punch.
    radii = sorted({x["radius_mm"] for x in ok})
    if not radii:
        return
    r0 = min(radii, key=lambda r: abs(r - 1.5))
    bonded = [s for s in STUDIES if s[0] in BONDED]
    fig, axes = plt.subplots(1, len(bonded), figsize=(4.2 * len(bonded), 3.9))
    for ax, (case, nu) in zip(axes, bonded):
        path = os.path.join(validate.REF_DIR, f"converged_{case}_nu{nu:g}.csv")
        ref = np.genfromtxt(path, delimiter=",", names=True)
        ax.plot(ref["displacement_mm"], ref["force_N"], "k-", lw=1.5, label="converged reference")
        ax.fill_between(ref["displacement_mm"], ref["force_N"] - ref["force_uncertainty_N"],
                        ref["force_N"] + ref["force_uncertainty_N"], color="grey", alpha=0.3,
                        lw=0, label="its uncertainty")
        for law, (style, colour, name) in STYLE.items():
            pts = [x for x in ok if x["case"] == case and x["nu"] == nu and x["law"] == law
                   and x["radius_mm"] == r0]
            if pts and os.path.exists(pts[0]["curve"]):
                d, F = validate.read_curve(pts[0]["curve"])
                ax.plot(d, F, style.replace(":", "-") if law.startswith("C3D") else style,
                        color=colour, ms=3, label=f"{name}, {pts[0]['spheres']} nodes")
        ax.set_title(f"{case}, nu = {nu:g}, r = {r0:g} mm")
        ax.set_xlabel("tool displacement (mm)")
        ax.set_ylabel("force (N)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(os.path.join(img, "validation_same_mesh.png"), dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    main()
