"""Box and cylindrical-specimen meshes and scene files for the indentation experiment (the
builder's input)."""

import json
import math
import os

W, H = 20.0, 10.0  # mm

# The paper's tissue (docs/physics.md section 10.6). The switch strain is not given; 10 % is ours (the
# same as examples/poke_block.cpp).
BILINEAR = {"density": 1050, "youngs_modulus": 13150, "viscosity": 10.26,
            "large_strain_modulus": 68380, "switch_strain": 0.1}
# The neo-Hookean reference's small-strain behaviour: E = 13.15 kPa, linear links.
LINEAR = {"density": 1050, "youngs_modulus": 13150, "viscosity": 10.26}


def write_box_off(path, divisions=4):
    """A closed, outward-oriented triangulated box [0, 20] x [0, 20] x [0, 10] mm; each face is
    split into divisions x divisions quads (a finer input surface than 12 triangles keeps the
    corner sampling of the filling symmetric)."""
    verts, index, faces = [], {}, []

    def v(p):
        key = tuple(round(c, 9) for c in p)
        if key not in index:
            index[key] = len(verts)
            verts.append(key)
        return index[key]

    size = (W, W, H)
    for axis in range(3):
        for side in (0, 1):
            u, w = (axis + 1) % 3, (axis + 2) % 3
            for a in range(divisions):
                for b in range(divisions):
                    q = []
                    for da, db in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        p = [0.0, 0.0, 0.0]
                        p[axis] = side * size[axis]
                        p[u] = (a + da) * size[u] / divisions
                        p[w] = (b + db) * size[w] / divisions
                        q.append(v(p))
                    # (u, w, axis) is right-handed, so (u, w) ordering faces +axis.
                    if side == 0:
                        q = q[::-1]
                    faces.append((q[0], q[1], q[2]))
                    faces.append((q[0], q[2], q[3]))
    write_off(path, verts, faces)


def write_disc_off(path, radius=10.0, segments=128):
    """The cylindrical specimen of validation/axisym.py: a closed, outward-oriented triangulated
    cylinder of `radius` (mm) and height H, its axis vertical through the box's centre (W/2, W/2),
    bottom at z = 0. A `segments`-gon prism: its volume is within (2 pi/segments)^2/6 (0.04 % at
    128) of the cylinder's; the rims are its only sharp edges (the side's facets meet at
    360/segments degrees), so the builder protects exactly them."""
    c = W / 2
    ring = [(c + radius * math.cos(2 * math.pi * k / segments),
             c + radius * math.sin(2 * math.pi * k / segments)) for k in range(segments)]
    verts = [(c, c, 0.0), (c, c, H)] + [(x, y, 0.0) for x, y in ring] + [(x, y, H) for x, y in ring]
    faces = []
    for k in range(segments):
        k1 = (k + 1) % segments
        b0, b1, t0, t1 = 2 + k, 2 + k1, 2 + segments + k, 2 + segments + k1
        faces.append((0, b1, b0))  # bottom, facing -z
        faces.append((1, t0, t1))  # top, facing +z
        faces.append((b0, b1, t1))  # side, facing outward
        faces.append((b0, t1, t0))
    write_off(path, verts, faces)


def write_off(path, verts, faces):
    """A triangle mesh as OFF: vertices (mm) and 0-based triangles."""
    with open(path, "w") as f:
        f.write(f"OFF\n{len(verts)} {len(faces)} 0\n")
        for p in verts:
            f.write(f"{p[0]:.9g} {p[1]:.9g} {p[2]:.9g}\n")
        for t in faces:
            f.write(f"3 {t[0]} {t[1]} {t[2]}\n")


def write_scene(path, mesh, topology="tetrahedral", radius=1.5, material=None, grid_spacing=None,
                neighbours=18, optimiser=None, graded=None):
    """A one-part scene in mm; the bottom layer is fixed by the scene (lowest spheres), the tool
    fixes the rest itself."""
    material = material or LINEAR
    part = {"name": "block", "mesh": os.path.relpath(mesh, os.path.dirname(os.path.abspath(path))),
            "topology": topology, "radius": radius, "material": material}
    if topology == "tetrahedral" and optimiser:
        part["optimiser"] = optimiser
    if topology == "tetrahedral" and graded:
        # Finer under the tool: size_min within `plateau` of the top's centre, growing to the
        # radius over `distance` (graded_tools.py).
        size_min, distance, plateau = graded
        part["metric"] = {"type": "graded", "size_min": size_min, "size_max": radius,
                          "centre": [W / 2, W / 2, H], "distance": distance,
                          "plateau_radius": plateau}
    if topology == "grid":
        s = grid_spacing or 2 * radius
        part["grid"] = {"neighbours": neighbours, "spacing": s}
        zfix = H  # anchors the build; fsm-indent then fixes exactly the lowest layer
    else:
        zfix = 1e-3
    scene = {"format": "fsm-scene", "version": 1, "name": os.path.basename(path)[:-5],
             "units": "mm", "parts": [part],
             "fixed": [{"part": "block", "box": {"min": [-1, -1, -1], "max": [W + 1, W + 1, zfix]}}]}
    with open(path, "w") as f:
        json.dump(scene, f, indent=1)
