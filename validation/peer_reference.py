#!/usr/bin/python3
"""The static sag of the peer benchmark's meshes (bench/bench_bullet.cpp), converged with CalculiX,
so that Bullet's and libfsm's sags can be judged against a reference rather than each other.

    FSM_BENCH_DUMP=/tmp/peer build/bench/bench_bullet --benchmark_filter=BM_FsmSameMeshStep \\
        --benchmark_min_time=0.0001                     # writes /tmp/peer/peer_<mesh>.json
    /usr/bin/python3 validation/peer_reference.py /tmp/peer/peer_cube.json \\
        /tmp/peer/peer_uterus_body.json [--levels 0,1,2] [--work /tmp/peer-fem]

For each mesh: the same geometry (the polyhedron the tetrahedra fill), the same fixed nodes, the
same material (CalculiX's NEO HOOKE from E and nu, as the continuum law's energy) and load
(gravity on the density; NLGEOM, static). Solved with C3D4 and C3D10 on the mesh refined
uniformly `level` times (each tetrahedron into 8 at its edges' midpoints). A node of a refined
mesh is fixed where the edge it halves joins two fixed nodes, so the fixed set is the same point
set at every level (the simplices spanned by fixed nodes). The measured quantity is the bench's:
the mean downward displacement of the measured nodes (the cube's top face, or the body's free
nodes), which are vertices of every level. The sags of the finest three C3D4 levels are
Richardson-extrapolated (observed order, GCI with Fs = 1.25); C3D10 at the two finest levels it
ran is the cross-check (`quadratic_sag_mm`, and `quadratic_change_mm` between its two levels).

With --libfsm-levels, libfsm's own continuum law (element and node-smoothed strains) is settled
to rest on the same refinements through the Python bindings: a second, independent
discretisation of the same problem (`libfsm_continuum`).

Writes validation/reference/peer_sag.json. ccx runs single-threaded.
"""
import argparse
import json
import os
import re
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import fem  # noqa: E402

# The 8-way split of a tetrahedron (corners 0-3, edge midpoints m01, m02, m03, m12, m13, m23):
# four corner tetrahedra and the inner octahedron cut along the m02-m13 diagonal.
_EDGES = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]


def refine(P, T, fixed):
    """One uniform refinement: (P', T', fixed'); the old vertices keep their indices."""
    mid, extra, fx = {}, [], list(fixed)

    def m(a, b):
        key = (min(a, b), max(a, b))
        if key not in mid:
            mid[key] = len(P) + len(extra)
            extra.append(0.5 * (P[a] + P[b]))
            fx.append(fixed[a] and fixed[b])
        return mid[key]

    out = []
    for t in T:
        v0, v1, v2, v3 = (int(x) for x in t)
        m01, m02, m03, m12, m13, m23 = (m(t[a], t[b]) for a, b in _EDGES)
        out += [[v0, m01, m02, m03], [m01, v1, m12, m13], [m02, m12, v2, m23], [m03, m13, m23, v3],
                [m01, m02, m03, m13], [m01, m02, m12, m13], [m02, m03, m13, m23],
                [m02, m12, m13, m23]]
    return np.vstack([P, np.array(extra)]), np.array(out, dtype=np.int64), fx


def refined(spec, level):
    """The spec's mesh (vertices in m, tetrahedra oriented, fixed flags) refined `level` times."""
    P = np.array(spec["vertices"], dtype=float)
    T = np.array(spec["tetrahedra"], dtype=np.int64)
    fixed = [False] * len(P)
    for i in spec["fixed"]:
        fixed[i] = True
    for _ in range(level):
        P, T, fixed = refine(P, T, fixed)
    return P, fem.oriented_tets(P, T), fixed


def write_inp(path, P, T, fixed, measured, spec, order, increments, confined=None):
    """P in mm; gravity on the density (t/mm^3, mm/s^2: forces in N). `confined` (an axis,
    0-2) holds every node in the two other directions (the self-check's uniaxial strain)."""
    if order == 2:
        n_lin = len(P)
        P, T = fem.quadratic_tets(P, T)
        fixed = list(fixed) + [False] * (len(P) - n_lin)
        # a mid-side node of an edge between two fixed vertices is fixed (the same point set)
        for t in T:
            for k, (a, b) in enumerate(fem.C3D10_EDGES):
                if fixed[t[a]] and fixed[t[b]]:
                    fixed[t[4 + k]] = True
    etype = "C3D4" if order == 1 else "C3D10"
    g = np.array(spec["gravity"], dtype=float) * 1e3  # m/s^2 -> mm/s^2
    gn = float(np.linalg.norm(g))
    fixed_ids = np.nonzero(np.array(fixed))[0] + 1
    with open(path, "w") as f:
        f.write(f"** libfsm peer reference: {spec['name']}, {etype}, {len(P)} nodes, {len(T)} tets\n")
        fem.write_tet_cards(f, P, T, etype, digits=10)
        fem.write_nset(f, "FIXED", fixed_ids)
        fem.write_nset(f, "MEASURED", np.array(measured) + 1)
        fem.write_neo_hooke(f, spec["youngs_modulus_pa"], spec["poisson_ratio"], spec["density"])
        f.write("*BOUNDARY\nFIXED, 1, 3, 0.\n")
        if confined is not None:
            for dof in sorted({0, 1, 2} - {confined}):
                f.write(f"NALL, {dof + 1}, {dof + 1}, 0.\n")
        # automatic incrementation (no contact here): a cut-back retries a smaller increment
        f.write("*STEP, NLGEOM, INC=10000\n*STATIC\n")
        f.write(f"{1.0 / increments:.9g}, 1.0, 1e-6, {1.0 / increments:.9g}\n")
        f.write(f"*DLOAD\nEALL, GRAV, {gn:.9g}, {g[0] / gn:.9g}, {g[1] / gn:.9g}, {g[2] / gn:.9g}\n")
        f.write("*NODE PRINT, NSET=MEASURED\nU\n*END STEP\n")
    return len(P), len(T)


def parse_u(path):
    """The last displacement block of the .dat: {node id: (ux, uy, uz)} and its time."""
    text = open(path).read()
    blocks = list(re.finditer(r"displacements \(vx,vy,vz\) for set MEASURED and time\s+([-+0-9.Ee]+)",
                              text))
    if not blocks:
        return None, {}
    b = blocks[-1]
    u = {}
    for line in text[b.end():].splitlines()[1:]:
        parts = line.split()
        if len(parts) != 4:
            if u:
                break
            continue
        u[int(parts[0])] = tuple(float(x) for x in parts[1:])
    return float(b.group(1)), u


def solve(spec, level, order, work, ccx, increments, confined=None, reuse=False):
    """One CalculiX run (or, with `reuse`, the .dat a finished earlier run of the same job left in
    `work`): the sag and the run's size and wall time (None when reused)."""
    P, T, fixed = refined(spec, level)
    P = P * 1e3  # m -> mm
    job = f"{spec['name']}_l{level}_o{order}"
    nodes, tets = write_inp(os.path.join(work, job + ".inp"), P, T, fixed, spec["measured"], spec,
                            order, increments, confined)
    dat = os.path.join(work, job + ".dat")
    t, u = parse_u(dat) if reuse and os.path.exists(dat) else (None, {})
    sec = None
    if t is None or abs(t - 1.0) > 1e-6 or len(u) != len(spec["measured"]):
        t0 = time.time()
        r = fem.run_ccx(work, job, ccx)
        sec = round(time.time() - t0, 1)
        t, u = parse_u(dat)
        if r.returncode != 0 or t is None or abs(t - 1.0) > 1e-6 or len(u) != len(spec["measured"]):
            raise RuntimeError(f"ccx failed on {job}: rc {r.returncode}, time {t}\n" + r.stdout[-1500:])
    # The sag: the mean displacement along the load's direction.
    down = np.array(spec["gravity"], dtype=float)
    down /= np.linalg.norm(down)
    sag = float(np.mean([np.dot(u[i + 1], down) for i in spec["measured"]]))
    return {"level": level, "order": order, "element": "C3D4" if order == 1 else "C3D10",
            "nodes": nodes, "tetrahedra": tets, "sag_mm": sag, "seconds": sec}


def libfsm_sag(spec, level, smoothing, dt):
    """libfsm's continuum law (Python bindings) on the mesh refined `level` times, settled to rest
    under the same load (implicit Euler at dt, drag 5/s, which leaves the equilibrium unchanged)
    until the sag changes by less than 1e-4 of itself in 0.5 s: an independent discretisation of
    the same problem, for the cross-check. Returns (sag, steps rolled back on the way)."""
    try:
        import fsm
    except ImportError:
        sys.path.insert(0, os.path.join(HERE, "..", "build", "python"))
        import fsm
    P, T, fixed = refined(spec, level)
    model = fsm.SphereModel()
    region = model.add_region("tissue", fsm.Material(
        density=spec["density"], youngs_modulus=spec["youngs_modulus_pa"],
        poisson_ratio=spec["poisson_ratio"], viscosity=10.26))
    fsm.add_tetrahedral_part(model, fsm.TetrahedralMesh(P, T.astype(np.int32)), region,
                             0.00125 / 2 ** level)
    for i, f in enumerate(fixed):
        if f:
            model.set_fixed(i)
    model.set_region_law(region, fsm.ForceLaw.continuum)
    sim = fsm.Simulation(model, gravity=np.array(spec["gravity"], dtype=float), drag=5.0,
                         strain_smoothing=smoothing)
    down = np.array(spec["gravity"], dtype=float) / np.linalg.norm(spec["gravity"])
    meas = spec["measured"]
    x0 = P[meas]
    prev, every, rolled_back = None, int(round(0.5 / dt)), 0
    for k in range(1, int(round(60 / dt))):
        if not sim.step(dt).advanced:  # rolled back (the state is kept); the next step retries
            rolled_back += 1
            if rolled_back > 20:
                raise RuntimeError(f"libfsm: {rolled_back} steps rolled back at level {level}")
        if k % every == 0:
            sag = float(np.mean((np.array(sim.model.positions)[meas] - x0) @ down)) * 1e3
            if prev is not None and abs(sag - prev) < 1e-4 * abs(sag):
                return sag, rolled_back
            prev = sag
    raise RuntimeError(f"libfsm: level {level} not at rest after 60 s")


def richardson(h, f):
    """Three meshes, h[0] > h[1] > h[2] with ratio 2: (extrapolated, GCI uncertainty, order)."""
    e1, e2 = f[1] - f[0], f[2] - f[1]
    if e1 * e2 <= 0 or e2 == 0:
        return f[2], abs(e2), None
    p = float(np.log(abs(e1 / e2)) / np.log(h[0] / h[1]))
    pc = min(max(p, 0.5), 3.0)
    fe = f[2] + e2 / (2 ** pc - 1)
    return fe, max(1.25 * abs(fe - f[2]), 0.0 if pc == p else abs(e2)), p


def selfcheck(work, ccx, tolerance):
    """A 2 x 2 x 10 mm column (Kuhn tetrahedra, 1 mm cells), its bottom fixed, every node held in
    the two directions across it, under its own weight along its axis (0.01 g: the strains stay
    near 2e-5, so the small-strain solution holds to about that), once along z and once along x
    (the sag is read along the load, whatever its direction): uniaxial strain, u_z(top) = -rho g L^2 / (2 M) with
    M = E (1 - nu) / ((1 + nu) (1 - 2 nu)), which a mesh of layers gives exactly at its nodes in
    both element orders (a 1-D problem). Refined once, the same: so the check covers refine() (a
    non-conforming split or a wrongly fixed mid-edge node changes the answer), the fixed set, the
    units of density and gravity, and the parsing. Returns the largest relative error."""
    idx, P = {}, []
    L = 10
    for k in range(L + 1):
        for j in range(3):
            for i in range(3):
                idx[(i, j, k)] = len(P)
                P.append([i * 1e-3, j * 1e-3, k * 1e-3])
    kuhn = [(0, 1, 3, 7), (0, 1, 5, 7), (0, 2, 3, 7), (0, 2, 6, 7), (0, 4, 5, 7), (0, 4, 6, 7)]
    T = []
    for k in range(L):
        for j in range(2):
            for i in range(2):
                c = [idx[(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1))] for b in range(8)]
                T += [[c[a] for a in t] for t in kuhn]
    spec = {"name": "selfcheck", "youngs_modulus_pa": 13150.0, "poisson_ratio": 0.45,
            "density": 1050.0, "gravity": [0.0, 0.0, -0.0981], "vertices": P, "tetrahedra": T,
            "fixed": [v for (i, j, k), v in idx.items() if k == 0],
            "measured": [v for (i, j, k), v in idx.items() if k == L]}
    E, nu = spec["youngs_modulus_pa"], spec["poisson_ratio"]
    M = E * (1 - nu) / ((1 + nu) * (1 - 2 * nu))
    exact = spec["density"] * 0.0981 * (L * 1e-3) ** 2 / (2 * M) * 1e3  # mm
    worst = 0.0
    for axis in (2, 0):
        # the column along `axis` (x and z swapped for axis 0; the swap mirrors the tetrahedra,
        # which write_inp reorients), loaded along -axis
        here = dict(spec, name=f"selfcheck_axis{axis}",
                    vertices=[[p[2], p[1], p[0]] if axis == 0 else p for p in P],
                    gravity=[-0.0981 if a == axis else 0.0 for a in range(3)])
        for order in (1, 2):
            for level in (0, 1):
                r = solve(here, level, order, work, ccx, 2, confined=axis)
                err = abs(r["sag_mm"] / exact - 1)
                worst = max(worst, err)
                print(f"axis {'xyz'[axis]}, {r['element']} level {level}: sag {r['sag_mm']:.6g} mm, "
                      f"exact {exact:.6g} mm, relative error {err:.2e}", flush=True)
    print("peer_reference self-check:", "ok" if worst <= tolerance else "FAILED", flush=True)
    return worst


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("meshes", nargs="*", help="peer_<mesh>.json files from bench_bullet")
    ap.add_argument("--selfcheck", action="store_true",
                    help="only the self-check against the exact sag of a confined column")
    ap.add_argument("--max-error", type=float, default=1e-3, help="the self-check's tolerance")
    ap.add_argument("--levels", default="0,1,2", help="C3D4 refinement levels")
    ap.add_argument("--quadratic-levels", default="0,1", help="C3D10 refinement levels")
    ap.add_argument("--increments", type=int, default=10)
    ap.add_argument("--reuse", action="store_true",
                    help="read the .dat of a run that finished earlier in --work instead of rerunning")
    ap.add_argument("--work", default="/tmp/fsm-peer-fem")
    ap.add_argument("--libfsm-levels", default="",
                    help="also settle libfsm's continuum law (element and node-smoothed strains) "
                    "on these refinement levels, through the Python bindings: the cross-check")
    ap.add_argument("--libfsm-dt", type=float, default=0.005, help="its time step (s)")
    ap.add_argument("--ccx", default="/usr/bin/ccx")
    ap.add_argument("--out", default=os.path.join(HERE, "reference", "peer_sag.json"))
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    if a.selfcheck:
        sys.exit(0 if selfcheck(a.work, a.ccx, a.max_error) <= a.max_error else 1)
    result = json.load(open(a.out)) if os.path.exists(a.out) else {}
    for path in a.meshes:
        spec = json.load(open(path))
        runs = []
        for order, levels in ((1, a.levels), (2, a.quadratic_levels)):
            for level in (int(x) for x in levels.split(",") if x):
                try:
                    r = solve(spec, level, order, a.work, a.ccx, a.increments, reuse=a.reuse)
                except RuntimeError as e:
                    r = {"level": level, "order": order, "failed": str(e)[:400]}
                print(spec["name"], r, flush=True)
                runs.append(r)
        lin = [r for r in runs if r["order"] == 1 and "sag_mm" in r]
        entry = {"mesh": {"nodes": len(spec["vertices"]), "tetrahedra": len(spec["tetrahedra"]),
                          "fixed": len(spec["fixed"]), "measured": len(spec["measured"])},
                 "material": {k: spec[k] for k in ("youngs_modulus_pa", "poisson_ratio", "density")},
                 "gravity": spec["gravity"], "runs": runs,
                 "command": "validation/peer_reference.py " + " ".join(sys.argv[1:]),
                 "when": time.strftime("%Y-%m-%d %H:%M")}
        if len(lin) >= 3:
            lin = sorted(lin, key=lambda r: r["level"])[-3:]
            fe, u, p = richardson([2.0 ** -r["level"] for r in lin], [r["sag_mm"] for r in lin])
            entry.update({"sag_mm": fe, "uncertainty_mm": u, "observed_order": p,
                          "from_levels": [r["level"] for r in lin]})
            print(f"{spec['name']}: converged sag {fe:.4f} +- {u:.2g} mm (p = {p})", flush=True)
        quad = sorted([r for r in runs if r["order"] == 2 and "sag_mm" in r], key=lambda r: r["level"])
        if len(quad) >= 2:
            # The quadratic elements' two finest levels: their change bounds what is left of
            # their discretisation error if they converge at order 1 or faster (ratio 2).
            entry.update({"quadratic_sag_mm": quad[-1]["sag_mm"],
                          "quadratic_change_mm": abs(quad[-1]["sag_mm"] - quad[-2]["sag_mm"])})
            print(f"{spec['name']}: C3D10 levels {quad[-2]['level']}, {quad[-1]['level']}: "
                  f"{quad[-2]['sag_mm']:.4f} -> {quad[-1]['sag_mm']:.4f} mm", flush=True)
        if a.libfsm_levels:
            cross = []
            for smoothing in ("element", "node"):
                for level in (int(x) for x in a.libfsm_levels.split(",") if x):
                    t0 = time.time()
                    sag, rolled_back = libfsm_sag(spec, level, smoothing, a.libfsm_dt)
                    cross.append({"level": level, "strain_smoothing": smoothing, "sag_mm": sag,
                                  "rolled_back_steps": rolled_back,
                                  "seconds": round(time.time() - t0, 1)})
                    print(spec["name"], "libfsm", cross[-1], flush=True)
            entry["libfsm_continuum"] = cross
        result[spec["name"]] = entry
        with open(a.out, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
