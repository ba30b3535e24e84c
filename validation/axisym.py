"""Reference FEM for the smooth indenters on a cylindrical specimen: CalculiX (ccx) axisymmetric.

The box's contact references do not converge for a flat-ended cylinder (its rim's contact failed
in ccx beyond n = 5-7 on the 3D quarter block; reference/README.md). Here the specimen is a
cylinder of radius RB = 10 mm and height H = 10 mm, bonded at the bottom, so the whole problem is
axisymmetric and one radial section is meshed (CAX8, quadratic, expanded by ccx into a 2-degree
wedge), many times finer than the 3D meshes at a fraction of their cost. The indenters are those
of fem.py: a rigid ball (R 5 mm), a rigid flat-ended cylinder (R 3 mm, sharp rim) and the same
with its rim rounded to 1 mm, frictionless, through surface-to-surface penalty contact, moved
down DEPTH in fixed increments. Units inside the .inp: mm, N, MPa.

Case names: "disc_sphere", "disc_cylinder", "disc_rounded_cylinder" (validation/reference/README.md,
"The cylindrical specimen"). libfsm runs the same geometry: validation/scenes.py writes the
specimen's closed surface, fsm-indent presses the same indenter into its top's centre.
"""

import os

import numpy as np

import fem

RB = 10.0  # mm: the specimen's radius
H = fem.H  # mm: its height
CASES = ("disc_rounded_cylinder", "disc_cylinder", "disc_sphere")
# ccx reports the forces of axisymmetric elements for their 2-degree wedge (checked: a CAX8 disc
# in frictionless uniaxial compression gives E pi R^2 eps / 180; check_wedge()).
WEDGE = 180.0
# Cells along every indenter's profile (the same on every mesh: its faceting error must not
# change with n).
PROFILE_CELLS = 96
# ccx's contact formulation (write_inp's `contact`). NODE TO SURFACE was tried on n = 30 and
# failed as well (reference/README.md).
CONTACT = "SURFACE TO SURFACE"
PENALTY = {"disc_sphere": 50.0, "disc_cylinder": 10.0, "disc_rounded_cylinder": 25.0}


def indenter_case(case):
    """fem.py's and fsm-indent's name of a case's indenter ("disc_sphere" -> "sphere"; a box case
    is its own)."""
    return case[len("disc_"):] if case.startswith("disc_") else case


def section_mesh(n, beta=fem.GRADING):
    """The specimen's radial section [0, RB] x [0, H] (x = r, y = z) as n x n CAX8 elements,
    graded toward the top's centre as fem.block_mesh grades the quarter block (elements (1 - beta)
    times the mean size at r = 0 and at the top). Returns (ids {(i, k) on the half grid: node},
    coords {node: (r, z)}, elements (8 nodes, CAX8 order), top elements)."""
    def cr(i):
        return RB * fem.graded(i / (2 * n), beta)

    def cz(k):
        return H - H * fem.graded(1 - k / (2 * n), beta)

    ids, coords = {}, {}
    for k in range(2 * n + 1):
        for i in range(2 * n + 1):
            if i % 2 and k % 2:
                continue
            v = len(ids) + 1
            ids[(i, k)] = v
            coords[v] = (cr(i), cz(k))
    elems, top = [], []
    for ek in range(n):
        for ei in range(n):
            i0, k0 = 2 * ei, 2 * ek
            corner = [(i0, k0), (i0 + 2, k0), (i0 + 2, k0 + 2), (i0, k0 + 2)]
            mid = [(i0 + 1, k0), (i0 + 2, k0 + 1), (i0 + 1, k0 + 2), (i0, k0 + 1)]
            elems.append([ids[c] for c in corner + mid])
            if ek == n - 1:
                top.append(len(elems))
    return ids, coords, elems, top


def profile(case, m, thickness=0.5):
    """The indenter's profile at rest (touching z = H on the axis) from the axis outward: m + 1
    surface points (r, z) and the points `thickness` inside the indenter, and the m midpoints of
    each. sphere: polar angle 0 to 80 deg; cylinder: the flat end (r <= 3) and 2 mm of side wall;
    rounded_cylinder: the flat end (r <= 2), the 1 mm rim and fem.WALL_H of side wall, cells equal
    in profile length."""
    ind = indenter_case(case)
    if ind == "sphere":
        R, tmax = fem.SPHERE_R, np.radians(80.0)
        s_total = tmax

        def at(t):  # t: the polar angle
            return ((R * np.sin(t), H + R - R * np.cos(t)),
                    ((R - thickness) * np.sin(t), H + R - (R - thickness) * np.cos(t)))
    elif ind == "rounded_cylinder":
        s_total = fem.ROUNDED_PROFILE_LENGTH

        def at(s):
            return fem.rounded_profile(s, thickness)
    elif ind == "cylinder":
        R, wall = fem.CYLINDER_R, 2.0
        s_total = R + wall

        def at(s):
            if s <= R:  # the inner points meet the wall's at the corner (R - t, H + t)
                return (s, H), (s * (R - thickness) / R, H + thickness)
            z = H + (s - R)
            return (R, z), (R - thickness, z + thickness)
    else:
        raise ValueError(case)
    if ind == "cylinder":
        # a node exactly at the sharp corner (s = R), the cells shared between the end and the
        # wall in proportion to their lengths
        n_end = int(round(m * R / s_total))
        s = np.concatenate([np.linspace(0, R, n_end + 1),
                            np.linspace(R, s_total, m - n_end + 1)[1:]])
    else:
        s = np.linspace(0, s_total, m + 1)
    mids = 0.5 * (s[1:] + s[:-1])
    return [at(x) for x in s], [at(x) for x in mids]


def write_inp(path, case, n, E_pa, nu, depth=fem.DEPTH, samples=10, beta=fem.GRADING, m=None,
              penalty=None, solver=None, contact=None):
    """The section (section_mesh) indented by the rigid indenter (a layer of CAX8 elements whose
    nodes are all prescribed; face S1 the contact surface) through frictionless surface-to-surface
    penalty contact; bottom bonded, the axis held radially. Outputs: RF totals on the indenter
    (set IND), U on the top's nodes (set TOPALL)."""
    ids, coords, elems, top = section_mesh(n, beta)
    m = m or PROFILE_CELLS
    penalty = penalty or PENALTY[case]
    pts, mids = profile(case, m)
    nn = len(coords)
    ind_nodes = {}
    ind_coords = {}

    def node(key, rz):
        if key not in ind_nodes:
            v = nn + 1 + len(ind_nodes)
            ind_nodes[key] = v
            ind_coords[v] = rz
        return ind_nodes[key]

    ind_elems = []
    for a in range(m):
        (p0, q0), (p1, q1), (pm, qm) = pts[a], pts[a + 1], mids[a]
        conn = [node(("p", a), p0), node(("p", a + 1), p1), node(("q", a + 1), q1),
                node(("q", a), q0), node(("pm", a), pm),
                node(("s", a + 1), tuple(0.5 * (np.array(p1) + np.array(q1)))),
                node(("qm", a), qm), node(("s", a), tuple(0.5 * (np.array(p0) + np.array(q0))))]
        P = [np.array(ind_coords[v]) for v in conn[:4]]
        area = 0.5 * sum(P[i][0] * P[(i + 1) % 4][1] - P[(i + 1) % 4][0] * P[i][1]
                         for i in range(4))
        if area <= 0:
            raise ValueError(f"indenter cell {a} is not counter-clockwise ({area})")
        ind_elems.append(conn)
    bottom = [v for (i, k), v in ids.items() if k == 0]
    axis = [v for (i, k), v in ids.items() if i == 0 and k > 0]
    top_all = [v for (i, k), v in ids.items() if k == 2 * n]
    with open(path, "w") as f:
        f.write(f"** libfsm validation: {case}, axisymmetric, {n}x{n} CAX8 graded beta={beta}, "
                f"E={E_pa} Pa, nu={nu}, penalty {penalty} MPa/mm\n")
        f.write("*NODE, NSET=NALL\n")
        for v in range(1, nn + 1):
            r, z = coords[v]
            f.write(f"{v}, {r:.9g}, {z:.9g}\n")
        f.write("*NODE, NSET=IND\n")
        for v, (r, z) in ind_coords.items():
            f.write(f"{v}, {r:.9g}, {z:.9g}\n")
        f.write("*ELEMENT, TYPE=CAX8, ELSET=EALL\n")
        for e, conn in enumerate(elems, 1):
            f.write(f"{e}, " + ", ".join(map(str, conn)) + "\n")
        ind_eids = list(range(len(elems) + 1, len(elems) + 1 + len(ind_elems)))
        f.write("*ELEMENT, TYPE=CAX8, ELSET=EIND\n")
        for e, conn in zip(ind_eids, ind_elems):
            f.write(f"{e}, " + ", ".join(map(str, conn)) + "\n")
        for name, s in (("BOTTOM", bottom), ("AXIS", axis), ("TOPALL", top_all)):
            fem.write_nset(f, name, s)
        f.write("*SURFACE, NAME=SSLAVE, TYPE=ELEMENT\n" + "".join(f"{e}, S3\n" for e in top))
        f.write("*SURFACE, NAME=SMASTER, TYPE=ELEMENT\n" + "".join(f"{e}, S1\n" for e in ind_eids))
        fem.write_neo_hooke(f, E_pa, nu)
        f.write("*MATERIAL, NAME=RIGID\n*ELASTIC\n1000., 0.3\n")
        f.write("*SOLID SECTION, ELSET=EIND, MATERIAL=RIGID\n")
        f.write("*SURFACE INTERACTION, NAME=SI1\n*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR\n")
        f.write(f"{penalty:.9g}\n")
        f.write(f"*CONTACT PAIR, INTERACTION=SI1, TYPE={contact or CONTACT}\nSSLAVE, SMASTER\n")
        f.write("*BOUNDARY\nBOTTOM, 1, 2, 0.\nAXIS, 1, 1, 0.\nIND, 1, 2, 0.\n")
        f.write(fem.step_cards(samples, solver))
        f.write(f"*BOUNDARY\nIND, 2, 2, {-depth:.9g}\n")
        f.write("*NODE PRINT, NSET=IND, TOTALS=ONLY\nRF\n")
        f.write("*NODE PRINT, NSET=TOPALL\nU\n")
        f.write("*END STEP\n")
    return coords, top_all


def penetration(case, coords, u, d, r_min=0.0):
    """Largest penetration (mm) of the specimen's top nodes (deformed) into the indenter moved down
    by d (fem.depth_inside, in the section: r = x, z = y), over the nodes at r >= r_min at rest.
    run_contact leaves out the element on the axis: its top face has no area at r = 0, so the
    contact holds it only weakly and it sinks into the indenter (65-300 um at 2.5 mm, halving with
    each halving of the mesh); the force it leaves out converges away with the mesh."""
    ind = indenter_case(case)
    return max([0.0] + [fem.depth_inside(ind, coords[v][0] + disp[0], coords[v][1] + disp[1], d)
                        for v, disp in u.items() if coords[v][0] >= r_min])


def run_contact(workdir, case, n, E_pa, nu, depth=fem.DEPTH, samples=10, ccx="/usr/bin/ccx",
                threads=1, refine=(1, 2), **kw):
    """Runs one axisymmetric reference; returns (displacement mm, force N of the whole specimen,
    largest penetration mm per sample, k) as fem.run_contact does."""
    os.makedirs(workdir, exist_ok=True)
    job = f"{case}_n{n}_nu{nu:g}".replace(".", "p")
    inp = os.path.join(workdir, job + ".inp")
    errors = []
    for k in refine:
        coords, _ = write_inp(inp, case, n, E_pa, nu, depth, samples * k, **kw)
        r = fem.run_ccx(workdir, job, ccx, threads)
        dat = os.path.join(workdir, job + ".dat")
        t, fy = fem.parse_dat_set(dat, "IND", axis=1)  # the axis is y
        if r.returncode == 0 and len(t) == samples * k and abs(t[-1] - 1.0) < 1e-6:
            break
        errors.append(f"{samples * k} increments: rc {r.returncode}, {len(t)} done\n"
                      + r.stdout[-1500:])
    else:
        raise RuntimeError(f"ccx failed on {job}:\n" + "\n".join(errors))
    us = fem.parse_dat_u(dat, "TOPALL")
    t, fy = t[k - 1::k], fy[k - 1::k]
    r_min = RB * fem.graded(1 / n, kw.get("beta", fem.GRADING)) - 1e-9  # the axis element's edge
    pen = [0.0] + [penetration(case, coords, us[ti], ti * depth, r_min) for ti in t]
    d = np.concatenate([[0.0], t * depth])
    F = np.concatenate([[0.0], -WEDGE * fy])
    return d, F, np.array(pen), k


def check_wedge(workdir, ccx="/usr/bin/ccx"):
    """The force scale of ccx's axisymmetric elements: one CAX8 disc (R = H = 10 mm, linear
    elastic E = 1000 MPa) compressed 0.1 % between frictionless platens is in uniaxial stress, so
    the whole disc's reaction is E pi R^2 eps; returns (WEDGE x ccx's total, that force)."""
    os.makedirs(workdir, exist_ok=True)
    with open(os.path.join(workdir, "wedge_check.inp"), "w") as f:
        f.write("*NODE, NSET=NALL\n1, 0, 0\n2, 5, 0\n3, 10, 0\n4, 0, 5\n5, 10, 5\n6, 0, 10\n"
                "7, 5, 10\n8, 10, 10\n*ELEMENT, TYPE=CAX8, ELSET=EALL\n1, 1, 3, 8, 6, 2, 5, 7, 4\n"
                "*NSET, NSET=BOT\n1, 2, 3\n*NSET, NSET=IND\n6, 7, 8\n*NSET, NSET=AXIS\n1, 4, 6\n"
                "*MATERIAL, NAME=M\n*ELASTIC\n1000., 0.3\n*SOLID SECTION, ELSET=EALL, MATERIAL=M\n"
                "*STEP\n*STATIC\n*BOUNDARY\nBOT, 2, 2, 0.\nAXIS, 1, 1, 0.\nIND, 2, 2, -0.01\n"
                "*NODE PRINT, NSET=IND, TOTALS=ONLY\nRF\n*END STEP\n")
    r = fem.run_ccx(workdir, "wedge_check", ccx)
    if r.returncode != 0:
        raise RuntimeError("ccx failed on the wedge check:\n" + r.stdout[-1500:])
    _, fy = fem.parse_dat_set(os.path.join(workdir, "wedge_check.dat"), "IND", axis=1)
    return -WEDGE * float(fy[-1]), 1000.0 * np.pi * RB ** 2 * 1e-3


if __name__ == "__main__":
    import sys
    got, want = check_wedge(sys.argv[1] if len(sys.argv) > 1 else "/tmp/fsm-axisym-check")
    print(f"CAX8 disc in uniaxial compression: {got:.6g} N from ccx x {WEDGE:g}, "
          f"exact {want:.6g} N")
    sys.exit(0 if abs(got / want - 1) < 1e-5 else 1)
