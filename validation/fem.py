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
  rate-independent, so the static increments are the samples).
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


def neo_hooke_constants(E_pa, nu):
    """C10 and D1 (MPa units) of CalculiX's NEO HOOKE for Young's modulus E (Pa), Poisson nu."""
    E = E_pa * 1e-6
    mu = E / (2 * (1 + nu))
    K = E / (3 * (1 - 2 * nu))
    return mu / 2, 2 / K


def write_inp(path, case, n, E_pa, nu, depth=DEPTH, samples=SAMPLES):
    """A quarter of the block, [10, 20] x [10, 20] x [0, 10] mm (both cases are symmetric about
    x = 10 and y = 10: symmetry conditions there), as a structured C3D20R mesh of n x n x n
    elements of 10/n mm; n must be a multiple of 5 for the punch's edge (2 mm from the centre)
    to lie on element boundaries."""
    nx, ny, nz = n, n, n
    hx, hy, hz = (W / 2) / nx, (W / 2) / ny, H / nz
    x0, y0 = W / 2, W / 2
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
                lines.append(f"{ids[(i, j, k)]}, {x0 + i * hx / 2:.9g}, {y0 + j * hy / 2:.9g}, {k * hz / 2:.9g}")
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
    c10, d1 = neo_hooke_constants(E_pa, nu)
    with open(path, "w") as f:
        f.write(f"** libfsm validation: {case}, {nx}x{ny}x{nz} C3D20R, E={E_pa} Pa, nu={nu}\n")
        f.write("*NODE, NSET=NALL\n" + "\n".join(lines) + "\n")
        f.write("*ELEMENT, TYPE=C3D20R, ELSET=EALL\n")
        for e, conn in enumerate(elems, 1):
            # at most 16 entries per line
            f.write(f"{e}, " + ", ".join(map(str, conn[:15])) + ",\n" + ", ".join(map(str, conn[15:])) + "\n")
        for name, s in (("BOTTOM", bottom), ("TOP", top), ("SYMX", sym_x), ("SYMY", sym_y)):
            f.write(f"*NSET, NSET={name}\n")
            for a in range(0, len(s), 16):
                f.write(", ".join(map(str, s[a:a + 16])) + ",\n")
        f.write("*MATERIAL, NAME=TISSUE\n*HYPERELASTIC, NEO HOOKE\n")
        f.write(f"{c10:.9g}, {d1:.9g}\n")
        f.write("*SOLID SECTION, ELSET=EALL, MATERIAL=TISSUE\n")
        f.write("*BOUNDARY\nBOTTOM, 1, 3, 0.\nTOP, 1, 2, 0.\nSYMX, 1, 1, 0.\nSYMY, 2, 2, 0.\n")
        f.write("*STEP, NLGEOM, INC=10000\n*STATIC, DIRECT\n")
        f.write(f"{1.0 / samples:.9g}, 1.0\n")
        f.write(f"*BOUNDARY\nTOP, 3, 3, {-depth:.9g}\n")
        f.write("*NODE PRINT, NSET=TOP, TOTALS=ONLY\nRF\n*END STEP\n")
    return len(ids), len(elems), len(top)


def parse_dat(path):
    """(time, total reaction force in z) per increment from a .dat with TOTALS=ONLY."""
    times, fz = [], []
    text = open(path).read()
    for m in re.finditer(r"total force \(fx,fy,fz\) for set TOP and time\s+([-+0-9.Ee]+)\s*\n\s*"
                         r"([-+0-9.Ee]+)\s+([-+0-9.Ee]+)\s+([-+0-9.Ee]+)", text):
        times.append(float(m.group(1)))
        fz.append(float(m.group(4)))
    return np.array(times), np.array(fz)


def run(workdir, case, n, E_pa, nu, depth=DEPTH, samples=SAMPLES, ccx="/usr/bin/ccx", threads=1):
    """Runs one reference; returns (displacement mm, force N) arrays starting at (0, 0)."""
    os.makedirs(workdir, exist_ok=True)
    job = f"{case}_n{n}_nu{nu:g}".replace(".", "p")
    inp = os.path.join(workdir, job + ".inp")
    write_inp(inp, case, n, E_pa, nu, depth, samples)
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), CCX_NPROC_EQUATION_SOLVER=str(threads))
    r = subprocess.run([ccx, "-i", job], cwd=workdir, env=env, capture_output=True, text=True)
    t, fz = parse_dat(os.path.join(workdir, job + ".dat"))
    if r.returncode != 0 or len(t) == 0 or abs(t[-1] - 1.0) > 1e-6:
        raise RuntimeError(f"ccx failed on {job}: rc {r.returncode}, {len(t)} increments\n"
                           + r.stdout[-2000:])
    d = np.concatenate([[0.0], t * depth])
    F = np.concatenate([[0.0], -4 * fz])  # whole block (4 quarters); compressive force positive
    return d, F


def have_ccx(ccx="/usr/bin/ccx"):
    return os.path.exists(ccx) or shutil.which("ccx") is not None
