"""Reference FEM for the indentation experiment: CalculiX (ccx) on a 20 x 20 x 10 mm block.

Writes the .inp (quadratic hexahedra C3D20R, neo-Hookean, nearly incompressible, NLGEOM), runs
ccx, parses the total reaction force on the loaded nodes at every increment. Units inside the
.inp: mm, N, MPa (so forces come out in N and displacements in mm).

Geometry and loading (docs/validation.md):
- block [0, 20] x [0, 20] x [0, 10] mm, bottom face fixed in x, y and z; a quarter is meshed
  (symmetry about x = 10 and y = 10), forces are reported for the whole block;
- "compression": every top node moved down by d, held in x and y (a bonded flat platen);
- "punch": the top nodes with |x - 10| <= 2 and |y - 10| <= 2 moved down by d, held in x and y
  (a bonded 4 x 4 mm flat punch; the mesh has element boundaries on the punch edges);
- d from 0 to 2.5 mm in 30 equal increments (5 mm/min sampled at 1 Hz; the material is
  rate-independent, so the static increments are the samples); `samples` sets another count.

Also: the contact cases "sphere" (rigid, R 5 mm) and "cylinder" (rigid flat end, R 3 mm),
frictionless, on a graded quarter block (write_contact_inp, run_contact); and C3D4 on a given
tetrahedral mesh of the full block (run_tet_mesh; command line `fem.py tetmesh MODEL.fsm CASE NU`
and `fem.py tetcheck`). See validation/reference/README.md.
"""

import os
import re
import shutil
import subprocess

import numpy as np

W, H = 20.0, 10.0  # mm
PUNCH = 4.0  # mm
DEPTH = 2.5  # mm
SAMPLES = 30


CCX_MEMORY_GB = float(os.environ.get("FSM_CCX_MEMORY_GB", 8))


def _limit_memory():
    """preexec_fn of the ccx runs: caps the address space (a shared machine; ccx 2.20's contact
    once grew past 20 GB) so that a runaway run fails instead of exhausting memory."""
    import resource
    lim = int(CCX_MEMORY_GB * 2 ** 30)
    resource.setrlimit(resource.RLIMIT_AS, (lim, lim))


def run_ccx(work, job, ccx="/usr/bin/ccx", threads=1):
    """ccx on work/job.inp with `threads` threads and the memory cap: the CompletedProcess."""
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), CCX_NPROC_EQUATION_SOLVER=str(threads))
    return subprocess.run([ccx, "-i", job], cwd=work, env=env, capture_output=True, text=True,
                          preexec_fn=_limit_memory)


def oriented_tets(P, T):
    """T (a copy) with every negatively oriented tetrahedron's corners 1 and 2 swapped; a
    degenerate tetrahedron (volume 0 to 1e-15 of the largest) is a ValueError."""
    T = np.array(T, dtype=np.int64)
    vol = np.einsum("ij,ij->i", np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]),
                    P[T[:, 3]] - P[T[:, 0]])
    flat = np.abs(vol) <= 1e-15 * np.max(np.abs(vol))
    if np.any(flat):
        raise ValueError(f"{int(np.sum(flat))} degenerate tetrahedra")
    T[vol < 0] = T[vol < 0][:, [0, 2, 1, 3]]
    return T


def write_nset(f, name, ids):
    """*NSET card of 1-based node ids, 16 per line."""
    f.write(f"*NSET, NSET={name}\n")
    for a in range(0, len(ids), 16):
        f.write(", ".join(map(str, ids[a:a + 16])) + ",\n")


def write_tet_cards(f, P, T, etype, digits=9):
    """*NODE (set NALL) and *ELEMENT (set EALL) cards of nodes P (mm) and 0-based elements T."""
    f.write("*NODE, NSET=NALL\n")
    for i, (x, y, z) in enumerate(P, 1):
        f.write(f"{i}, {x:.{digits}g}, {y:.{digits}g}, {z:.{digits}g}\n")
    f.write(f"*ELEMENT, TYPE={etype}, ELSET=EALL\n")
    for e, t in enumerate(T, 1):
        f.write(f"{e}, " + ", ".join(str(int(v) + 1) for v in t) + "\n")


def write_neo_hooke(f, E_pa, nu, density_kg_m3=None):
    """The material TISSUE (CalculiX NEO HOOKE from E and nu; *DENSITY in t/mm^3 if given) and
    the solid section of EALL."""
    c10, d1 = neo_hooke_constants(E_pa, nu)
    f.write(f"*MATERIAL, NAME=TISSUE\n*HYPERELASTIC, NEO HOOKE\n{c10:.9g}, {d1:.9g}\n")
    if density_kg_m3 is not None:
        f.write(f"*DENSITY\n{density_kg_m3 * 1e-12:.9g}\n")
    f.write("*SOLID SECTION, ELSET=EALL, MATERIAL=TISSUE\n")


def neo_hooke_constants(E_pa, nu):
    """C10 and D1 (MPa units) of CalculiX's NEO HOOKE for Young's modulus E (Pa), Poisson nu."""
    E = E_pa * 1e-6
    mu = E / (2 * (1 + nu))
    K = E / (3 * (1 - 2 * nu))
    return mu / 2, 2 / K


EDGE_GRADING = 0.6  # "compression_graded": elements 0.4x the mean size at the singular edges


def edge_graded(s, beta=EDGE_GRADING):
    """[0, 1] -> [0, 1], elements (1 - beta) times the mean size at s = 1 (the free side faces of
    the quarter block, x = 20 or y = 20) and (1 + beta) times at s = 0 (the symmetry planes)."""
    return 1 - graded(1 - s, beta)


def edge_graded_z(s, beta=EDGE_GRADING):
    """[0, 1] -> [0, 1], elements (1 - beta) times the mean size at both ends (the bonded bottom
    and top) and (1 + beta) times at mid-height: the quadratic map of graded() mirrored."""
    return 0.5 * graded(2 * s, beta) if s <= 0.5 else 1 - 0.5 * graded(2 * (1 - s), beta)


def write_inp(path, case, n, E_pa, nu, depth=DEPTH, samples=SAMPLES, solver=None):
    """A quarter of the block, [10, 20] x [10, 20] x [0, 10] mm (both cases are symmetric about
    x = 10 and y = 10: symmetry conditions there), as a structured C3D20R mesh of n x n x n
    elements of 10/n mm; n must be a multiple of 5 for the punch's edge (2 mm from the centre)
    to lie on element boundaries.
    "compression_graded": the compression case on a mesh graded toward its singular edges (where
    the free side faces meet the bonded bottom and top: x or y = 20 mm at z = 0 and 10 mm), with
    the same map (edge_graded, edge_graded_z) for every n, so the meshes form one family with
    h ~ 1/n whose elements at those edges are 0.4 times the uniform mesh's."""
    graded_edges = case == "compression_graded"
    if graded_edges:
        case = "compression"
    nx, ny, nz = n, n, n
    hx, hy, hz = (W / 2) / nx, (W / 2) / ny, H / nz
    x0, y0 = W / 2, W / 2

    def coords(i, j, k):  # half-grid index -> coordinates
        if not graded_edges:
            return x0 + i * hx / 2, y0 + j * hy / 2, k * hz / 2
        # Corner nodes on the map; mid-side nodes halfway between their corners (straight-sided
        # elements with centred mid-side nodes: an affine element map, which a mid-side node
        # placed on the curved map would distort).
        def on(f, a, m):
            return f(a / (2 * m)) if a % 2 == 0 else 0.5 * (f((a - 1) / (2 * m)) + f((a + 1) / (2 * m)))
        return (x0 + (W / 2) * on(edge_graded, i, nx), y0 + (W / 2) * on(edge_graded, j, ny),
                H * on(edge_graded_z, k, nz))
    # Node grid at half spacing; keep only nodes that belong to some element (no face/body
    # centres): a point (i, j, k) on the half grid is used unless two or more indices are odd.
    ids = {}
    lines = []
    for k in range(2 * nz + 1):
        for j in range(2 * ny + 1):
            for i in range(2 * nx + 1):
                if (i % 2) + (j % 2) + (k % 2) >= 2:
                    continue
                ids[(i, j, k)] = len(ids) + 1
                x, y, z = coords(i, j, k)
                lines.append(f"{ids[(i, j, k)]}, {x:.9g}, {y:.9g}, {z:.9g}")
    elems = []
    for ez in range(nz):
        for ey in range(ny):
            for ex in range(nx):
                i0, j0, k0 = 2 * ex, 2 * ey, 2 * ez
                c = [(0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0), (0, 0, 2), (2, 0, 2), (2, 2, 2), (0, 2, 2)]
                mid = [(1, 0, 0), (2, 1, 0), (1, 2, 0), (0, 1, 0), (1, 0, 2), (2, 1, 2), (1, 2, 2), (0, 1, 2),
                       (0, 0, 1), (2, 0, 1), (2, 2, 1), (0, 2, 1)]
                conn = [ids[(i0 + a, j0 + b, k0 + d)] for a, b, d in c + mid]
                elems.append(conn)
    bottom = [v for (i, j, k), v in ids.items() if k == 0]
    sym_x = [v for (i, j, k), v in ids.items() if i == 0]
    sym_y = [v for (i, j, k), v in ids.items() if j == 0]
    top_all = [(i, j, v) for (i, j, k), v in ids.items() if k == 2 * nz]
    if case == "compression":
        top = [v for _, _, v in top_all]
    elif case == "punch":
        tol = 1e-9
        top = [v for i, j, v in top_all
               if i * hx / 2 <= PUNCH / 2 + tol and j * hy / 2 <= PUNCH / 2 + tol]
    else:
        raise ValueError(case)
    with open(path, "w") as f:
        f.write(f"** libfsm validation: {case}, {nx}x{ny}x{nz} C3D20R"
                f"{' graded toward the bonded edges' if graded_edges else ''}, E={E_pa} Pa, nu={nu}\n")
        f.write("*NODE, NSET=NALL\n" + "\n".join(lines) + "\n")
        f.write("*ELEMENT, TYPE=C3D20R, ELSET=EALL\n")
        for e, conn in enumerate(elems, 1):
            # at most 16 entries per line
            f.write(f"{e}, " + ", ".join(map(str, conn[:15])) + ",\n" + ", ".join(map(str, conn[15:])) + "\n")
        for name, s in (("BOTTOM", bottom), ("TOP", top), ("SYMX", sym_x), ("SYMY", sym_y)):
            write_nset(f, name, s)
        write_neo_hooke(f, E_pa, nu)
        f.write("*BOUNDARY\nBOTTOM, 1, 3, 0.\nTOP, 1, 2, 0.\nSYMX, 1, 1, 0.\nSYMY, 2, 2, 0.\n")
        f.write(step_cards(samples, solver))
        f.write(f"*BOUNDARY\nTOP, 3, 3, {-depth:.9g}\n")
        f.write("*NODE PRINT, NSET=TOP, TOTALS=ONLY\nRF\n*END STEP\n")
    return len(ids), len(elems), len(top)


def step_cards(samples, solver=None):
    """The NLGEOM static step with `samples` fixed increments (DIRECT: every increment is a sample;
    a diverging increment stops ccx, and the run_* functions then retry with more increments).
    Automatic incrementation with *TIME POINTS was tried and dropped: after a cutback, ccx 2.20
    inserted zero-length increments, whose contact matrix was singular."""
    out = "*STEP, NLGEOM, INC=10000\n"
    out += f"*STATIC, SOLVER={solver}, DIRECT\n" if solver else "*STATIC, DIRECT\n"
    out += f"{1.0 / samples:.9g}, 1.0\n"
    return out


def parse_dat(path):
    """(time, total reaction force in z) per increment from a .dat with TOTALS=ONLY (set TOP)."""
    return parse_dat_set(path, "TOP")


def run(workdir, case, n, E_pa, nu, depth=DEPTH, samples=SAMPLES, ccx="/usr/bin/ccx", threads=1,
        solver=None, refine=(1, 2, 3), keep_partial=False):
    """Runs one reference; returns (displacement mm, force N) arrays starting at (0, 0). If ccx
    fails (a diverging fixed increment: e.g. n = 15 compression with 0.5 mm steps), retries with
    k times the increments for each k in `refine` and keeps every k-th. With keep_partial, a run
    that fails every time returns the increments its last attempt completed (every k-th) and sets
    run.partial; otherwise it raises."""
    run.partial = False
    os.makedirs(workdir, exist_ok=True)
    job = f"{case}_n{n}_nu{nu:g}".replace(".", "p")
    inp = os.path.join(workdir, job + ".inp")
    errors = []
    for k in refine:
        write_inp(inp, case, n, E_pa, nu, depth, samples * k, solver)
        r = run_ccx(workdir, job, ccx, threads)
        t, fz = parse_dat(os.path.join(workdir, job + ".dat"))
        if r.returncode == 0 and len(t) == samples * k and abs(t[-1] - 1.0) < 1e-6:
            break
        errors.append(f"{samples * k} increments: rc {r.returncode}, {len(t)} done\n" + r.stdout[-1500:])
    else:
        if not keep_partial or len(t) < k:
            raise RuntimeError(f"ccx failed on {job}:\n" + "\n".join(errors))
        run.partial = True
        t, fz = t[:len(t) - len(t) % k], fz[:len(t) - len(t) % k]
    t, fz = t[k - 1::k], fz[k - 1::k]
    d = np.concatenate([[0.0], t * depth])
    F = np.concatenate([[0.0], -4 * fz])  # whole block (4 quarters); compressive force positive
    run.last_refine = k
    return d, F


def have_ccx(ccx="/usr/bin/ccx"):
    return os.path.exists(ccx) or shutil.which("ccx") is not None


# ---------------------------------------------------------------------------------------------
# Smooth indenters through real contact: a rigid sphere (R = 5 mm) and a rigid flat-ended
# cylinder (R = 3 mm), frictionless, on the same quarter block.

SPHERE_R = 5.0  # mm
CYLINDER_R = 3.0  # mm
# rounded_cylinder: the same cylinder with its rim rounded to EDGE_R (a flat end of radius
# CYLINDER_R - EDGE_R). The sharp rim's contact did not converge in ccx beyond n = 5 (README).
EDGE_R = 1.0  # mm
WALL_H = 2.5  # mm of straight side wall above the rounded rim
CONTACT_CASES = ("sphere", "cylinder", "rounded_cylinder")
GRADING = 0.5  # x = 10 + 10 (g s + (1 - g) s^2) style grading, see graded()
# MPa/mm: the pressure-overclosure slope (linear penalty). The cylinder's sharp edge made Newton
# diverge at 50 on n = 10 (contact status chatter at the rim); 10 keeps its nodal penetration
# well below 1 % of the displacement (mean pressure ~0.015 MPa -> ~1.5 um at 2.5 mm). The rounded
# cylinder's first increment diverged at 50 on n = 5; at 25 its top nodes penetrate 9 um at most.
PENALTY = {"sphere": 50.0, "cylinder": 10.0, "rounded_cylinder": 25.0}
# Cells per side of the indenter's quarter-disc surface mesh, the same on every block mesh (the
# faceting error must not change with n): sphere 80 deg / 32 cells, chord sagitta 1.2 um; cylinder
# rim 32 segments per 90 deg, sagitta 0.9 um (the flat end itself is exact).
# rounded_cylinder: 48 cells along its 5.07 mm profile (flat end, rim, wall), 0.1-0.15 mm each:
# a sagitta of at most about 3 um on the rim.
INDENTER_CELLS = {"sphere": 32, "cylinder": 16, "rounded_cylinder": 48}


# The rounded cylinder's profile from its axis outward: the flat end, the rim, WALL_H of wall.
ROUNDED_PROFILE_LENGTH = (CYLINDER_R - EDGE_R) + 0.5 * np.pi * EDGE_R + WALL_H


def rounded_profile(s, thickness):
    """The rounded cylinder at rest (its end on z = H, its axis at r = 0): the (r, z) of its
    surface at profile length s from the axis, and of the point `thickness` inside it."""
    R, e = CYLINDER_R, EDGE_R
    flat, arc = R - e, 0.5 * np.pi * e
    if s <= flat:
        return (s, H), (s, H + thickness)
    if s <= flat + arc:
        a = (s - flat) / e  # angle from the downward normal
        c = (flat, H + e)  # the rim's centre
        return ((c[0] + e * np.sin(a), c[1] - e * np.cos(a)),
                (c[0] + (e - thickness) * np.sin(a), c[1] - (e - thickness) * np.cos(a)))
    z = H + e + (s - flat - arc)
    return (R, z), (R - thickness, z)


def graded(s, beta=GRADING):
    """Maps the uniform parameter s in [0, 1] to [0, 1] with elements (1 - beta) times the mean
    size at s = 0 and (1 + beta) times at s = 1 (quadratic map: sizes grow linearly). The same
    map on every mesh, so the meshes of a family differ only in n (h ~ 1/n)."""
    return (1 - beta) * s + beta * s * s


def block_mesh(n, beta=0.0):
    """The quarter block [10, 20] x [10, 20] x [0, 10] mm as n x n x n C3D20R elements.
    beta = 0: uniform; beta > 0: graded toward the top's centre (x = y = 10, z = 10): the element
    size goes from (1 - beta) 10/n at the centre/top to (1 + beta) 10/n at the far side/bottom.
    Returns (ids {(i, j, k) on the half grid: node id}, coords {id: (x, y, z)}, elements)."""
    x0 = W / 2

    def cx(i):  # half-grid index -> coordinate
        return x0 + (W / 2) * graded(i / (2 * n), beta)

    def cz(k):
        return H - H * graded(1 - k / (2 * n), beta)

    ids, coords = {}, {}
    for k in range(2 * n + 1):
        for j in range(2 * n + 1):
            for i in range(2 * n + 1):
                if (i % 2) + (j % 2) + (k % 2) >= 2:
                    continue
                v = len(ids) + 1
                ids[(i, j, k)] = v
                coords[v] = (cx(i), cx(j), cz(k))
    c = [(0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0), (0, 0, 2), (2, 0, 2), (2, 2, 2), (0, 2, 2)]
    mid = [(1, 0, 0), (2, 1, 0), (1, 2, 0), (0, 1, 0), (1, 0, 2), (2, 1, 2), (1, 2, 2), (0, 1, 2),
           (0, 0, 1), (2, 0, 1), (2, 2, 1), (0, 2, 1)]
    elems = []
    for ez in range(n):
        for ey in range(n):
            for ex in range(n):
                i0, j0, k0 = 2 * ex, 2 * ey, 2 * ez
                elems.append([ids[(i0 + a, j0 + b, k0 + d)] for a, b, d in c + mid])
    return ids, coords, elems


def _disc(u, v):
    """The unit square [0, 1]^2 onto the unit quarter disc (elliptical grid mapping): smooth, no
    degenerate cells, the edges u = 0 and v = 0 on the axes."""
    return u * np.sqrt(1 - v * v / 2), v * np.sqrt(1 - u * u / 2)


def indenter_mesh(case, m, first_node, first_elem, thickness=0.5, wall=False):
    """A rigid indenter's contact surface as one layer of C3D8 elements (all nodes prescribed, so
    they are rigid) whose face S1 is the indenter's surface, for the quarter x, y >= 10 mm, at rest
    just touching the top (z = 10) at the centre. m: cells per quarter-disc side.
    sphere: the lower quarter hemisphere up to a polar angle of 80 deg (r = 4.92 mm);
    cylinder: the flat end (r <= 3) and, with wall=True, the side wall up to 2 mm above it;
    rounded_cylinder: the flat end (r <= 2), the rim rounded to 1 mm, and the side wall up to
    WALL_H above the rim, as one revolved grid (cells equal in profile length).
    Returns (node lines, element lines, element ids, node ids)."""
    pts = []  # surface point, inward point (into the indenter)
    if case == "sphere":
        R = SPHERE_R
        zc = H + R
        tmax = np.radians(80.0)
        grid = {}
        for b in range(m + 1):
            for a in range(m + 1):
                X, Y = _disc(a / m, b / m)
                rho = np.hypot(X, Y)
                th = rho * tmax
                if rho > 0:
                    dx, dy = X / rho, Y / rho
                else:
                    dx, dy = 0.0, 0.0
                out = (W / 2 + R * np.sin(th) * dx, W / 2 + R * np.sin(th) * dy, zc - R * np.cos(th))
                Ri = R - thickness
                inn = (W / 2 + Ri * np.sin(th) * dx, W / 2 + Ri * np.sin(th) * dy, zc - Ri * np.cos(th))
                grid[(a, b)] = len(pts)
                pts.append((out, inn))
        cells = [((a, b), (a + 1, b), (a + 1, b + 1), (a, b + 1)) for b in range(m) for a in range(m)]
    elif case == "rounded_cylinder":
        total = ROUNDED_PROFILE_LENGTH
        grid = {}
        for b in range(m + 1):
            for a in range(m + 1):
                X, Y = _disc(a / m, b / m)
                rho = np.hypot(X, Y)
                dx, dy = (X / rho, Y / rho) if rho > 0 else (0.0, 0.0)
                (ro, zo), (ri, zi) = rounded_profile(rho * total, thickness)
                grid[(a, b)] = len(pts)
                pts.append(((W / 2 + ro * dx, W / 2 + ro * dy, zo), (W / 2 + ri * dx, W / 2 + ri * dy, zi)))
        cells = [((a, b), (a + 1, b), (a + 1, b + 1), (a, b + 1)) for b in range(m) for a in range(m)]
    elif case == "cylinder":
        R = CYLINDER_R
        grid = {}
        for b in range(m + 1):
            for a in range(m + 1):
                X, Y = _disc(a / m, b / m)
                out = (W / 2 + R * X, W / 2 + R * Y, H)
                sc = (R - thickness) / R  # the inner face shrunk so the rim cells meet the wall's
                inn = (W / 2 + R * sc * X, W / 2 + R * sc * Y, H + thickness)
                grid[(a, b)] = len(pts)
                pts.append((out, inn))
        cells = [((a, b), (a + 1, b), (a + 1, b + 1), (a, b + 1)) for b in range(m) for a in range(m)]
        # the side wall: without it, the block's surface near the edge moved inward under the
        # flat end's rim and ended inside the cylinder (0.41 mm on n = 7, see penetration());
        # with it (and a penalty of 50 MPa/mm) ccx 2.20 diverged on n = 10 and grew past 20 GB
        rim = [(m, b) for b in range(m + 1)] + [(a, m) for a in range(m - 1, -1, -1)]
        nwall = max(2, m // 3) if wall else 0
        for r_i in range(1, nwall + 1):
            z = H + 2.0 * (r_i / nwall) ** 1.5  # finer near the edge
            for q, (a, b) in enumerate(rim):
                X, Y = _disc(a / m, b / m)
                rr = np.hypot(X, Y)
                dx, dy = X / rr, Y / rr
                out = (W / 2 + R * dx, W / 2 + R * dy, z)
                inn = (W / 2 + (R - thickness) * dx, W / 2 + (R - thickness) * dy, z + thickness)
                grid[("w", r_i, q)] = len(pts)
                pts.append((out, inn))
        for r_i in range(nwall):
            for q in range(len(rim) - 1):
                lo0 = rim[q] if r_i == 0 else ("w", r_i, q)
                lo1 = rim[q + 1] if r_i == 0 else ("w", r_i, q + 1)
                cells.append((lo0, lo1, ("w", r_i + 1, q + 1), ("w", r_i + 1, q)))
    else:
        raise ValueError(case)
    node_lines, nid = [], {}
    for key, idx in grid.items():
        nid[key] = (first_node + 2 * idx, first_node + 2 * idx + 1)
        out, inn = pts[idx]
        node_lines.append(f"{nid[key][0]}, {out[0]:.9g}, {out[1]:.9g}, {out[2]:.9g}")
        node_lines.append(f"{nid[key][1]}, {inn[0]:.9g}, {inn[1]:.9g}, {inn[2]:.9g}")
    xyz = {}
    for key, idx in grid.items():
        xyz[nid[key][0]], xyz[nid[key][1]] = pts[idx]
    elem_lines, eids = [], []
    for e, cell in enumerate(cells):
        o = [nid[k][0] for k in cell]
        i = [nid[k][1] for k in cell]
        conn = o + i
        # positive Jacobian: (p2 - p1) x (p4 - p1) . (p5 - p1) > 0, else reverse the faces' order
        P = [np.array(xyz[v]) for v in conn]
        if np.dot(np.cross(P[1] - P[0], P[3] - P[0]), P[4] - P[0]) < 0:
            o, i = o[::-1], i[::-1]
            conn = o + i
        eid = first_elem + e
        eids.append(eid)
        elem_lines.append(f"{eid}, " + ", ".join(map(str, conn)))
    all_nodes = sorted(v for pair in nid.values() for v in pair)
    return node_lines, elem_lines, eids, all_nodes


def write_contact_inp(path, case, n, E_pa, nu, depth=DEPTH, samples=10, beta=GRADING, m=None,
                      penalty=None, solver=None, wall=True):
    """The quarter block (graded toward the contact, see block_mesh) indented by a rigid,
    frictionless sphere or flat-ended cylinder through surface-to-surface penalty contact; the
    indenter's nodes are all prescribed (rigid), x and y fixed, z moved down by `depth` in
    `samples` fixed increments. Outputs: RF totals on the indenter (set IND), U on the top's
    nodes (set TOPALL) for the penetration check."""
    ids, coords, elems = block_mesh(n, beta)
    m = m or INDENTER_CELLS[case]
    penalty = penalty or PENALTY[case]
    nn = len(ids)
    ind_nodes, ind_elems, ind_eids, ind_ids = indenter_mesh(case, m, nn + 1, len(elems) + 1,
                                                            wall=wall)
    bottom = [v for (i, j, k), v in ids.items() if k == 0]
    sym_x = [v for (i, j, k), v in ids.items() if i == 0]
    sym_y = [v for (i, j, k), v in ids.items() if j == 0]
    top_all = [v for (i, j, k), v in ids.items() if k == 2 * n]
    with open(path, "w") as f:
        f.write(f"** libfsm validation: {case} contact, {n}x{n}x{n} C3D20R graded beta={beta}, "
                f"E={E_pa} Pa, nu={nu}, penalty {penalty} MPa/mm\n")
        f.write("*NODE, NSET=NALL\n")
        for v in range(1, nn + 1):
            x, y, z = coords[v]
            f.write(f"{v}, {x:.9g}, {y:.9g}, {z:.9g}\n")
        f.write("*NODE, NSET=IND\n" + "\n".join(ind_nodes) + "\n")
        f.write("*ELEMENT, TYPE=C3D20R, ELSET=EALL\n")
        for e, conn in enumerate(elems, 1):
            f.write(f"{e}, " + ", ".join(map(str, conn[:15])) + ",\n" + ", ".join(map(str, conn[15:])) + "\n")
        f.write("*ELEMENT, TYPE=C3D8, ELSET=EIND\n" + "\n".join(ind_elems) + "\n")
        for name, s in (("BOTTOM", bottom), ("TOPALL", top_all), ("SYMX", sym_x), ("SYMY", sym_y)):
            write_nset(f, name, s)
        # top faces of the top layer of elements (face S2 = nodes 5-8 of C3D20R)
        top_elems = [e for e in range(1, len(elems) + 1) if (e - 1) // (n * n) == n - 1]
        f.write("*SURFACE, NAME=SSLAVE, TYPE=ELEMENT\n")
        f.write("".join(f"{e}, S2\n" for e in top_elems))
        f.write("*SURFACE, NAME=SMASTER, TYPE=ELEMENT\n")
        f.write("".join(f"{e}, S1\n" for e in ind_eids))
        write_neo_hooke(f, E_pa, nu)
        # the indenter: any material (all its nodes are prescribed)
        f.write("*MATERIAL, NAME=RIGID\n*ELASTIC\n1000., 0.3\n")
        f.write("*SOLID SECTION, ELSET=EIND, MATERIAL=RIGID\n")
        f.write("*SURFACE INTERACTION, NAME=SI1\n*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR\n")
        f.write(f"{penalty:.9g}\n")
        f.write("*CONTACT PAIR, INTERACTION=SI1, TYPE=SURFACE TO SURFACE\nSSLAVE, SMASTER\n")
        f.write("*BOUNDARY\nBOTTOM, 1, 3, 0.\nSYMX, 1, 1, 0.\nSYMY, 2, 2, 0.\nIND, 1, 3, 0.\n")
        f.write(step_cards(samples, solver))
        f.write(f"*BOUNDARY\nIND, 3, 3, {-depth:.9g}\n")
        f.write("*NODE PRINT, NSET=IND, TOTALS=ONLY\nRF\n")
        f.write("*NODE PRINT, NSET=TOPALL\nU\n")
        f.write("*END STEP\n")
    return nn, len(elems), coords, top_all


def parse_dat_set(path, nset, axis=2):
    """(time, total reaction force along `axis`: 0 x, 1 y, 2 z) per increment for the node set
    `nset` (TOTALS=ONLY)."""
    times, f = [], []
    text = open(path).read()
    for mm in re.finditer(r"total force \(fx,fy,fz\) for set " + nset + r" and time\s+([-+0-9.Ee]+)\s*\n\s*"
                          r"([-+0-9.Ee]+)\s+([-+0-9.Ee]+)\s+([-+0-9.Ee]+)", text):
        times.append(float(mm.group(1)))
        f.append(float(mm.group(2 + axis)))
    return np.array(times), np.array(f)


def parse_dat_u(path, nset):
    """{time: {node: (ux, uy, uz)}} from *NODE PRINT U blocks for `nset`."""
    out = {}
    text = open(path).read()
    blocks = re.split(r"\n\s*displacements \(vx,vy,vz\) for set ", text)
    for b in blocks[1:]:
        head, _, body = b.partition("\n")
        name, _, t = head.partition(" and time")
        if name.strip().upper() != nset.upper():
            continue
        u = {}
        for line in body.split("\n"):
            parts = line.split()
            if len(parts) == 4:
                try:
                    u[int(parts[0])] = tuple(float(x) for x in parts[1:])
                except ValueError:
                    break
            elif parts:
                break
        out[float(t)] = u
    return out


def depth_inside(case, r, z, d):
    """How deep (mm; negative outside) a point at distance r from the indenter's axis and height z
    lies inside the indenter moved down by d from touching z = H: sphere, R - |p - c|; cylinder,
    z - (H - d) where r <= R; rounded_cylinder, minus the signed distance to its profile (a
    rectangle with corners rounded to EDGE_R). The box's and the cylindrical specimen's
    references (axisym.py) both measure penetration with it."""
    if case == "sphere":
        return SPHERE_R - np.hypot(r, z - (H + SPHERE_R - d))
    if case == "rounded_cylinder":
        qx = r - (CYLINDER_R - EDGE_R)
        qz = (H - d + EDGE_R) - z  # the end face at H - d, the rim's centres above it
        return -(np.hypot(max(qx, 0.0), max(qz, 0.0)) + min(max(qx, qz), 0.0) - EDGE_R)
    return z - (H - d) if r <= CYLINDER_R else 0.0


def penetration(case, coords, u, d):
    """Largest penetration (mm) of the block's top nodes (deformed) into the indenter moved
    down by d (depth_inside; the indenter's axis is x = y = 10 mm)."""
    worst = 0.0
    for v, (ux, uy, uz) in u.items():
        x, y, z = coords[v]
        r = np.hypot(x + ux - W / 2, y + uy - W / 2)
        worst = max(worst, depth_inside(case, r, z + uz, d))
    return worst


def run_contact(workdir, case, n, E_pa, nu, depth=DEPTH, samples=10, ccx="/usr/bin/ccx", threads=1,
                refine=(1, 2), **kw):
    """Runs one contact reference; returns (displacement mm, force N, largest penetration mm per
    sample, k), all starting at 0. If ccx fails (a diverging fixed increment), retries with k
    times the increments for each k in `refine` and keeps every k-th (the samples do not
    change)."""
    os.makedirs(workdir, exist_ok=True)
    job = f"{case}_n{n}_nu{nu:g}".replace(".", "p")
    inp = os.path.join(workdir, job + ".inp")
    errors = []
    for k in refine:
        _, _, coords, _ = write_contact_inp(inp, case, n, E_pa, nu, depth, samples * k, **kw)
        r = run_ccx(workdir, job, ccx, threads)
        dat = os.path.join(workdir, job + ".dat")
        t, fz = parse_dat_set(dat, "IND")
        if r.returncode == 0 and len(t) == samples * k and abs(t[-1] - 1.0) < 1e-6:
            break
        errors.append(f"{samples * k} increments: rc {r.returncode}, {len(t)} done\n" + r.stdout[-1500:])
    else:
        raise RuntimeError(f"ccx failed on {job}:\n" + "\n".join(errors))
    us = parse_dat_u(dat, "TOPALL")
    t, fz = t[k - 1::k], fz[k - 1::k]
    pen = [0.0] + [penetration(case, coords, us[ti], ti * depth) for ti in t]
    d = np.concatenate([[0.0], t * depth])
    F = np.concatenate([[0.0], -4 * fz])  # the indenter pushes down: its reaction is upward
    return d, F, np.array(pen), k


# ---------------------------------------------------------------------------------------------
# Same-mesh linear tetrahedra: CalculiX C3D4 on a given tetrahedral mesh (e.g. a libfsm model's).

# C3D10's mid-side nodes: node 5 on edge 1-2, 6 on 2-3, 7 on 3-1, 8 on 1-4, 9 on 2-4, 10 on 3-4.
C3D10_EDGES = ((0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3))


def quadratic_tets(P, T):
    """The mesh (P, T) with a node at the midpoint of every edge: (P2, T10), T10 in C3D10's node
    order. The mid-side nodes are straight (the block's faces are flat)."""
    mid, extra = {}, []
    T10 = np.empty((len(T), 10), dtype=np.int64)
    T10[:, :4] = T
    for e, t in enumerate(T):
        for k, (a, b) in enumerate(C3D10_EDGES):
            key = (min(t[a], t[b]), max(t[a], t[b]))
            if key not in mid:
                mid[key] = len(P) + len(extra)
                extra.append(0.5 * (P[t[a]] + P[t[b]]))
            T10[e, 4 + k] = mid[key]
    return np.vstack([P, np.array(extra).reshape(-1, 3)]), T10


def write_tet_inp(path, case, nodes_mm, tets, nu, E=13150.0, depth=DEPTH, samples=SAMPLES,
                  order=1, confined=False):
    """The full block (no symmetry) as C3D4 (order 1) or C3D10 (order 2: the same tetrahedra with
    straight mid-side nodes) elements on the given mesh; bottom nodes (z within 1e-6 mm of the
    lowest z) bonded; the tool's nodes (top face: z within 1e-6 mm of the highest z; compression
    all of them, punch those with |x - 10| <= 2 and |y - 10| <= 2 mm) held in x, y and moved down
    by `depth`. Tetrahedra with a negative orientation are flipped. `confined` holds every node
    in x and y (uniaxial strain, for the self-check)."""
    P = np.asarray(nodes_mm, dtype=float)
    T = oriented_tets(P, tets)
    if order == 2:
        P, T = quadratic_tets(P, T)
    elif order != 1:
        raise ValueError(f"order {order}: 1 (C3D4) or 2 (C3D10)")
    etype = "C3D4" if order == 1 else "C3D10"
    tol = 1e-6
    zmin, zmax = P[:, 2].min(), P[:, 2].max()
    bottom = np.nonzero(P[:, 2] < zmin + tol)[0] + 1
    top = np.nonzero(P[:, 2] > zmax - tol)[0]
    if case == "compression":
        tool = top
    elif case == "punch":
        cx, cy = W / 2, W / 2
        tool = top[(np.abs(P[top, 0] - cx) <= PUNCH / 2 + 1e-9) & (np.abs(P[top, 1] - cy) <= PUNCH / 2 + 1e-9)]
    else:
        raise ValueError(case)
    if len(tool) == 0:
        raise ValueError(f"{case}: no tool nodes on the top face (z = {zmax:g} mm)")
    tool = tool + 1
    with open(path, "w") as f:
        f.write(f"** libfsm validation: {case}, {etype} on a given mesh ({len(P)} nodes, {len(T)} tets), "
                f"E={E} Pa, nu={nu}\n")
        write_tet_cards(f, P, T, etype)
        for name, sel in (("BOTTOM", bottom), ("TOP", tool)):
            write_nset(f, name, sel)
        write_neo_hooke(f, E, nu)
        f.write("*BOUNDARY\nBOTTOM, 1, 3, 0.\nTOP, 1, 2, 0.\n")
        if confined:
            f.write("NALL, 1, 2, 0.\n")
        f.write(step_cards(samples))
        f.write(f"*BOUNDARY\nTOP, 3, 3, {-depth:.9g}\n")
        f.write("*NODE PRINT, NSET=TOP, TOTALS=ONLY\nRF\n*END STEP\n")
    return len(bottom), len(tool)


def run_tet_mesh(work, case, nodes_mm, tets, nu, E=13150.0, depth=DEPTH, samples=SAMPLES,
                 ccx="/usr/bin/ccx", threads=1, job=None, order=1, confined=False):
    """CalculiX C3D4 (order 1) or C3D10 (order 2) (NLGEOM, the same neo-Hookean) on a tetrahedral
    mesh of the full block: nodes_mm (N, 3) in mm, tets (T, 4) node indices from 0. Returns
    (displacements mm, forces N) at samples + 1 points (0 included); the force is the whole tool's
    (no symmetry factor)."""
    os.makedirs(work, exist_ok=True)
    job = job or f"tet{order}_{case}_nu{nu:g}".replace(".", "p")
    write_tet_inp(os.path.join(work, job + ".inp"), case, nodes_mm, tets, nu, E, depth, samples,
                  order, confined)
    r = run_ccx(work, job, ccx, threads)
    t, fz = parse_dat(os.path.join(work, job + ".dat"))
    if r.returncode != 0 or len(t) == 0 or abs(t[-1] - 1.0) > 1e-6:
        raise RuntimeError(f"ccx failed on {job}: rc {r.returncode}, {len(t)} increments\n"
                           + r.stdout[-2000:])
    return np.concatenate([[0.0], t * depth]), np.concatenate([[0.0], -fz])


def load_fsm_tets(path):
    """(nodes mm (N, 3), tets (T, 4)) of a libfsm model file, through the Python bindings."""
    try:
        import fsm
    except ImportError:
        import sys
        sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "build",
                                        "python"))
        import fsm
    m = fsm.load_model(path)
    P = np.array(m.spheres.rest_positions, dtype=float) * 1000.0  # m -> mm
    T = np.array(m.spheres.tetrahedra, dtype=np.int64)
    if T.size == 0:
        raise ValueError(f"{path}: the model has no tetrahedra")
    return P, T


def tet_selfcheck(work, nu=0.49, E=13150.0, ccx="/usr/bin/ccx", order=1):
    """run_tet_mesh on a 2 x 2 x 1 mm block (2 x 2 x 1 cubes, 6 tetrahedra each) compressed by
    0.25 mm with every node held in x and y (C3D10's mid-height mid-side nodes too), so the
    deformation is homogeneous uniaxial strain, stretch l = 1 - d / 1 mm, which both element
    orders represent exactly (a C3D10 mid-side node on the wrong edge makes ccx refuse the
    element, a non-positive Jacobian, so the check also guards C3D10_EDGES), and the exact force
    of ccx's neo-Hookean
    W = C10 (J^(-2/3) I1 - 3) + (J - 1)^2 / D1 is F = -A (4/3 C10 (l^(1/3) - l^(-5/3))
    + 2 (l - 1) / D1) (small strain: A M eps, M = E (1 - nu) / ((1 + nu)(1 - 2 nu))).
    Returns rows (d, F_ccx, F_exact, F_small_strain) and the largest relative difference."""
    idx, P = {}, []
    for k in range(2):
        for j in range(3):
            for i in range(3):
                idx[(i, j, k)] = len(P)
                P.append((W / 2 - 1 + i, W / 2 - 1 + j, float(k)))
    kuhn = [(0, 1, 3, 7), (0, 1, 5, 7), (0, 2, 3, 7), (0, 2, 6, 7), (0, 4, 5, 7), (0, 4, 6, 7)]
    T = []
    for j in range(2):
        for i in range(2):
            c = [idx[(i + (b & 1), j + ((b >> 1) & 1), (b >> 2) & 1)] for b in range(8)]
            T += [[c[a] for a in t] for t in kuhn]
    d, F = run_tet_mesh(work, "compression", np.array(P), np.array(T), nu, E, depth=0.25,
                        samples=10, ccx=ccx, job=f"tet{order}_selfcheck", order=order,
                        confined=True)
    c10, d1 = neo_hooke_constants(E, nu)
    lam = 1 - d
    Fx = -4.0 * (c10 * 4 / 3 * (lam ** (1 / 3) - lam ** (-5 / 3)) + 2 * (lam - 1) / d1)
    M = E * 1e-6 * (1 - nu) / ((1 + nu) * (1 - 2 * nu))
    rel = np.max(np.abs(F[1:] - Fx[1:]) / Fx[1:])
    return [(a, b, c, 4.0 * M * a) for a, b, c in zip(d, F, Fx)], rel


def _main(argv):
    import argparse
    import sys
    import json
    import time
    ap = argparse.ArgumentParser(description="CalculiX C3D4 or C3D10 on a libfsm model's "
                                 "tetrahedral mesh: fem.py tetmesh MODEL.fsm CASE NU [--order 2]; "
                                 "prints JSON")
    ap.add_argument("command", choices=["tetmesh", "tetcheck"],
                    help="tetcheck: the uniaxial-strain check of run_tet_mesh (tet_selfcheck)")
    ap.add_argument("model", nargs="?")
    ap.add_argument("case", nargs="?", choices=["compression", "punch"])
    ap.add_argument("nu", nargs="?", type=float)
    ap.add_argument("--E", type=float, default=13150.0, help="Pa")
    ap.add_argument("--depth", type=float, default=DEPTH, help="mm")
    ap.add_argument("--work", default=None)
    ap.add_argument("--ccx", default="/usr/bin/ccx")
    ap.add_argument("--order", type=int, choices=[1, 2], default=1,
                    help="1: C3D4 on the tetrahedra; 2: C3D10, the same with mid-side nodes")
    ap.add_argument("--max-error", type=float, default=None,
                    help="tetcheck: exit 1 when the relative error exceeds this")
    a = ap.parse_args(argv)
    import tempfile
    work = a.work or tempfile.mkdtemp(prefix="fsm_tet_")
    if a.command == "tetcheck":
        rows, rel = tet_selfcheck(work, a.nu if a.nu is not None else 0.49, a.E, a.ccx, a.order)
        print(json.dumps({"check": "uniaxial strain, 2 x 2 x 1 mm, "
                          + ("C3D4" if a.order == 1 else "C3D10"), "max_relative_error": rel,
                          "rows_d_Fccx_Fexact_Fsmallstrain": rows}))
        if a.max_error is not None and not rel <= a.max_error:
            sys.exit(f"tetcheck: relative error {rel:.3g} above {a.max_error:g}")
        return
    if a.model is None or a.case is None or a.nu is None:
        ap.error("tetmesh needs MODEL CASE NU")
    P, T = load_fsm_tets(a.model)
    t0 = time.time()
    d, F = run_tet_mesh(work, a.case, P, T, a.nu, a.E, a.depth, ccx=a.ccx, order=a.order)
    print(json.dumps({"model": a.model, "case": a.case, "nu": a.nu, "E_pa": a.E,
                      "element": "C3D4" if a.order == 1 else "C3D10", "nodes": len(P),
                      "tetrahedra": len(T), "work": work, "seconds": round(time.time() - t0, 1),
                      "displacement_mm": [round(x, 6) for x in d],
                      "force_N": [float(f"{x:.6g}") for x in F]}))


if __name__ == "__main__":
    import sys
    _main(sys.argv[1:])
