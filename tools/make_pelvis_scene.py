#!/usr/bin/env python3
"""Writes a pelvis-sized scene: the Visible Human Female uterus and left adnexa of
data/vhf-pelvis/left_adnexa.json plus their mirror images as the right adnexa.

The shared data set has the left side only; the right side is the left one reflected in the
body's mid-sagittal plane (x -> 2 * x0 - x, x0 = the uterus' centre, faces reversed so that
they still face outward). The mirrored meshes are derived files: they go to OUT, never into
the repository.

    /usr/bin/python3 tools/make_pelvis_scene.py OUT [--shared DIR] [--uterus-gap CM]
                                                  [--uterus-radius CM]
    build/src/builder/fsm-build OUT/pelvis.json -o pelvis.fsm

Standard library only.
"""

import argparse
import copy
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SCENE = os.path.join(ROOT, "data", "vhf-pelvis", "left_adnexa.json")


def read_obj(path):
    """Vertices (list of [x, y, z]) and the other lines of an OBJ file."""
    vertices, faces = [], []
    with open(path, encoding="utf-8") as f:
        for line in f:
            w = line.split()
            if not w:
                continue
            if w[0] == "v":
                vertices.append([float(c) for c in w[1:4]])
            elif w[0] == "f":
                faces.append(w[1:])
    return vertices, faces


def write_mirrored_obj(src, dst, x0):
    vertices, faces = read_obj(src)
    with open(dst, "w", encoding="utf-8") as f:
        f.write(f"# {os.path.basename(src)} reflected in x = {x0!r} (tools/make_pelvis_scene.py)\n")
        for x, y, z in vertices:
            f.write(f"v {2 * x0 - x!r} {y!r} {z!r}\n")
        for face in faces:  # reversed: a reflection turns the winding inside out
            f.write("f " + " ".join(reversed(face)) + "\n")


def mesh_centre_x(paths):
    xs = []
    for p in paths:
        xs.extend(v[0] for v in read_obj(p)[0])
    return 0.5 * (min(xs) + max(xs))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", help="folder for pelvis.json and the mirrored meshes")
    ap.add_argument("--shared", default=os.path.join(ROOT, "..", "shared", "data", "vhf-pelvis"),
                    help="the shared vhf-pelvis meshes (default: ../shared/data/vhf-pelvis)")
    ap.add_argument("--uterus-gap", type=float, default=1.5,
                    help="attachment tolerance (scene units, cm) between the uterus and the "
                         "mirrored right parts (default 1.5)")
    ap.add_argument("--uterus-radius", type=float, default=None,
                    help="the uterus' sphere radius (scene units, cm; default the left scene's "
                         "0.3); 0.23 gives about 2,000 spheres in all")
    a = ap.parse_args()
    shared = os.path.abspath(a.shared)
    if not os.path.isdir(shared):
        sys.exit(f"make_pelvis_scene: {shared}: no such folder (the shared VHF meshes)")
    os.makedirs(a.out, exist_ok=True)
    with open(SCENE, encoding="utf-8") as f:
        scene = json.load(f)

    def shared_path(p):  # the scene names ../../../shared/data/vhf-pelvis/NAME
        return os.path.join(shared, os.path.basename(p))

    def meshes(part):
        return part.get("meshes") or [part["mesh"]]

    uterus = next(p for p in scene["parts"] if p["name"] == "uterus")
    x0 = mesh_centre_x([shared_path(m) for m in meshes(uterus)])

    out = copy.deepcopy(scene)
    out["name"] = "vhf-pelvis-bilateral"
    right_parts = []
    for part in out["parts"]:
        part_meshes = [shared_path(m) for m in meshes(part)]
        if "meshes" in part:
            part["meshes"] = part_meshes
        else:
            part["mesh"] = part_meshes[0]
        if part["name"] == "uterus":
            if a.uterus_radius is not None:
                part["radius"] = a.uterus_radius
            continue
        mirrored = copy.deepcopy(part)
        mirrored["name"] = part["name"].replace("_left", "_right")
        names = []
        for m in part_meshes:
            dst = os.path.join(os.path.abspath(a.out), "mirrored_" + os.path.basename(m))
            write_mirrored_obj(m, dst, x0)
            names.append(dst)
        if "meshes" in mirrored:
            mirrored["meshes"] = names
        else:
            mirrored["mesh"] = names[0]
        right_parts.append(mirrored)
    out["parts"] += right_parts

    def right(name):
        return name.replace("_left", "_right")

    # The VHF uterus is not symmetric (its right horn sits about a centimetre from where the
    # reflected left tube and ligament end), so the mirrored side's attachments to the uterus
    # reach across that gap: a stand-in for the right adnexa, sized and joined like the left.
    for att in scene["attachments"]:
        if not any("_left" in n for n in att["parts"]):
            continue
        m = dict(att, parts=[right(n) for n in att["parts"]])
        if "uterus" in att["parts"]:
            m["tolerance"] = max(att["tolerance"], a.uterus_gap)
        out["attachments"].append(m)
    # Fixed sets: the uterus' box is central; a left part's plane is mirrored (x components).
    extra = []
    for fx in scene.get("fixed", []):
        if "_left" not in fx["part"]:
            continue
        m = copy.deepcopy(fx)
        m["part"] = right(fx["part"])
        if "plane" in m:
            m["plane"]["normal"][0] = -m["plane"]["normal"][0]
            metres = {"m": 1.0, "cm": 0.01, "mm": 0.001}
            x0_scene = x0 * metres[scene.get("mesh_units", "m")] / metres[scene.get("units", "m")]
            m["plane"]["point"][0] = 2 * x0_scene - m["plane"]["point"][0]
        if "box" in m:
            raise SystemExit("make_pelvis_scene: mirroring a box of a left part is not supported")
        extra.append(m)
    out["fixed"] = scene.get("fixed", []) + extra
    path = os.path.join(a.out, "pelvis.json")
    with open(path, "w", encoding="utf-8") as f:
        json.dump(out, f, indent=2)
        f.write("\n")
    print(path)


if __name__ == "__main__":
    main()
