#!/usr/bin/python3
"""Writes organ.glb for the tutorial (docs/tutorial.md): a glTF 2.0 binary with two nodes, as
anatomy downloads come, in metres (glTF's unit):

* "organ": an ellipsoid 60 x 40 x 30 mm (semi-axes 30, 20, 15 mm) at the origin;
* "duct": a slender ellipsoid 50 x 8 x 8 mm, placed by its node's translation so that its inner
  end sinks 5 mm into the organ's side.

    make_organ_glb.py OUT.glb

Only numpy and the standard library: the GLB framing (a JSON chunk and a binary chunk) is simple.
"""
import json
import struct
import sys

import numpy as np


def icosphere(subdivisions):
    t = (1 + 5 ** 0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t),
         (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
         (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    v = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(subdivisions):
        mid, faces = {}, []

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = v[a] + v[b]
                v.append(p / np.linalg.norm(p))
                mid[key] = len(v) - 1
            return mid[key]

        for a, b, c in f:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            faces += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = faces
    return np.array(v), np.array(f, dtype=np.uint32)


def write_glb(path, meshes, nodes, roots):
    """meshes: [(name, vertices float32 (n, 3), faces uint32 (m, 3))]; nodes: glTF node dicts."""
    doc = {"asset": {"version": "2.0", "generator": "libfsm tutorial"}, "scene": 0,
           "scenes": [{"nodes": roots}], "nodes": nodes, "meshes": [], "accessors": [],
           "bufferViews": []}
    blob = b""
    for name, xyz, tri in meshes:
        views = []
        for data in (xyz.astype("<f4").tobytes(), tri.astype("<u4").tobytes()):
            blob += b"\0" * (-len(blob) % 4)
            doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
            blob += data
            views.append(len(doc["bufferViews"]) - 1)
        doc["accessors"] += [
            {"bufferView": views[0], "componentType": 5126, "count": len(xyz), "type": "VEC3",
             "min": xyz.min(axis=0).tolist(), "max": xyz.max(axis=0).tolist()},
            {"bufferView": views[1], "componentType": 5125, "count": tri.size, "type": "SCALAR"}]
        k = len(doc["accessors"])
        doc["meshes"].append({"name": name, "primitives": [
            {"attributes": {"POSITION": k - 2}, "indices": k - 1, "mode": 4}]})
    blob += b"\0" * (-len(blob) % 4)
    doc["buffers"] = [{"byteLength": len(blob)}]
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + len(blob)
    with open(path, "wb") as f:
        f.write(struct.pack("<4sII", b"glTF", 2, total))
        f.write(struct.pack("<I4s", len(text), b"JSON") + text)
        f.write(struct.pack("<I4s", len(blob), b"BIN\0") + blob)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "organ.glb"
    unit, faces = icosphere(3)
    organ = unit * (0.030, 0.020, 0.015)
    duct = unit * (0.025, 0.004, 0.004)  # centred on its node; the node moves it
    write_glb(out, [("organ", organ, faces), ("duct", duct, faces)],
              [{"name": "organ", "mesh": 0},
               {"name": "duct", "mesh": 1, "translation": [0.050, 0.0, 0.0]}],
              [0, 1])
    print(f"wrote {out}: nodes 'organ' (60 x 40 x 30 mm) and 'duct' (50 x 8 mm), in metres")


if __name__ == "__main__":
    main()
