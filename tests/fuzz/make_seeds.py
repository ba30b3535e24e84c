#!/usr/bin/env python3
"""Writes the mesh and scene seeds of the fuzzers into corpus/ (committed; run again after a
format change). The model-file seeds are model files the builder wrote (tests/data and a tiny
block, see README). Deterministic: the same files every run."""
import json
import shutil
import struct
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
FORMAT = {"obj": 0, "off": 1, "stl": 2, "ply": 3}  # fuzz_mesh.cpp: first byte picks the format

# A unit cube: 8 corners, 6 quads (12 triangles), outward.
V = [(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)]
QUADS = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
TRIS = [t for q in QUADS for t in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))]


def mesh_seed(name, fmt, data):
    if isinstance(data, str):
        data = data.encode()
    (HERE / "corpus" / "fuzz_mesh" / name).write_bytes(bytes([FORMAT[fmt]]) + data)


def seeds_mesh():
    obj = "".join("v %g %g %g\n" % p for p in V)
    obj += "".join("f %d %d %d %d\n" % tuple(i + 1 for i in q) for q in QUADS)
    mesh_seed("cube.obj", "obj", "# a cube\nmtllib x.mtl\n" + obj + "vn 0 0 1\ng side\n")
    mesh_seed("relative.obj", "obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3/1/1 -2/2/2 -1/3/3\n")
    off = "OFF\n%d %d 0\n" % (len(V), len(QUADS)) + "".join("%g %g %g\n" % p for p in V)
    off += "".join("4 %d %d %d %d\n" % q for q in QUADS)
    mesh_seed("cube.off", "off", off)
    mesh_seed("counts_on_header.off", "off", "OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 255 0 0\n")
    stl = "solid cube\n"
    for t in TRIS:
        stl += " facet normal 0 0 0\n  outer loop\n"
        stl += "".join("   vertex %g %g %g\n" % V[i] for i in t)
        stl += "  endloop\n endfacet\n"
    mesh_seed("cube_ascii.stl", "stl", stl + "endsolid cube\n")
    binary = b"binary cube".ljust(80, b" ") + struct.pack("<I", len(TRIS))
    for t in TRIS:
        binary += struct.pack("<3f", 0, 0, 0)
        for i in t:
            binary += struct.pack("<3f", *V[i])
        binary += b"\0\0"
    mesh_seed("cube_binary.stl", "stl", binary)
    header = ("ply\nformat %s 1.0\ncomment cube\nelement vertex 8\nproperty float x\n"
              "property float y\nproperty float z\nproperty uchar red\nelement face 6\n"
              "property list uchar int vertex_indices\nend_header\n")
    ascii_ply = header % "ascii" + "".join("%g %g %g 255\n" % p for p in V)
    ascii_ply += "".join("4 %d %d %d %d\n" % q for q in QUADS)
    mesh_seed("cube_ascii.ply", "ply", ascii_ply)
    for order, fmt in (("<", "binary_little_endian"), (">", "binary_big_endian")):
        data = (header % fmt).encode()
        for p in V:
            data += struct.pack(order + "3fB", *p, 255)
        for q in QUADS:
            data += struct.pack(order + "B4i", 4, *q)
        mesh_seed("cube_%s.ply" % fmt, "ply", data)


def seeds_scene():
    for scene in (ROOT / "data" / "uterus" / "uterus.json",
                  ROOT / "data" / "vhf-pelvis" / "left_adnexa.json"):
        shutil.copy(scene, HERE / "corpus" / "fuzz_scene" / scene.name)
    small = {
        "format": "fsm-scene", "version": 1, "name": "every key", "units": "mm",
        "mesh_units": "cm",
        "parts": [
            {"name": "block", "mesh": "cube.off", "topology": "tetrahedral", "radius": 2,
             "material": {"density": 1050, "youngs_modulus": 13150, "viscosity": 10.26,
                          "large_strain_modulus": 68380, "switch_strain": 0.1},
             "metric": {"type": "graded", "size_min": 1, "size_max": 3, "centre": [0, 0, 0],
                        "distance": 5, "plateau_radius": 1},
             "optimiser": "odt", "repair": {"orient": True}},
            {"name": "tube", "meshes": ["cube.obj", "cube.stl"], "mesh_units": "mm",
             "topology": "axis", "radius": 1,
             "material": {"density": 1000, "youngs_modulus": 5000},
             "repair": {"alpha_wrap": {"alpha": 1, "offset": 0.1}},
             "axis": {"spacing": 1, "radius_min": 0.5, "radius_max": 2, "bending": False}},
            {"name": "grid", "mesh": "cube.ply", "topology": "grid", "radius": 1,
             "material": {"density": 1000, "youngs_modulus": 5000},
             "grid": {"neighbours": 18, "spacing": 2}},
            {"name": "pack", "mesh": "cube.obj", "topology": "packing", "radius": 1,
             "material": {"density": 1000, "youngs_modulus": 5000},
             "packing": {"radius_min": 0.5, "radius_max": 2}},
            {"name": "aniso", "mesh": "cube.obj", "topology": "tetrahedral", "radius": 1,
             "material": {"density": 1000, "youngs_modulus": 5000},
             "metric": {"type": "anisotropic", "sizes": [1, 2, 3],
                        "axes": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}}],
        "attachments": [{"parts": ["block", "tube"], "tolerance": 1, "stiffness_scale": 2}],
        "fixed": [{"part": "block", "box": {"min": [0, 0, 0], "max": [1, 1, 1]}},
                  {"part": "block", "plane": {"point": [0, 0, 0], "normal": [0, 0, 1]}},
                  {"part": "grid", "vertices": [0, 1, 2]},
                  {"part": "tube", "chain_end": "last"}],
        "limits": {"spheres": 1000, "elements": 10000, "memory_gb": 1}}
    (HERE / "corpus" / "fuzz_scene" / "every_key.json").write_text(json.dumps(small, indent=1))


if __name__ == "__main__":
    seeds_mesh()
    seeds_scene()
