#!/usr/bin/python3
"""Test: fsm-demo on a model that is not the bundled uterus (the Visible Human left adnexa, whose
parts are named uterus, ovary_left, tube_left, ...) probes each of its parts, and --export writes a
ParaView series that meshio reads back consistent with the model.

    check_export.py FSM_DEMO SHARED_DATA_DIR SOURCE_DIR WORK_DIR

Exit status 77 (a skip for CTest) when the shared Visible Human meshes are not on this machine.
"""
import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import meshio
import numpy as np

demo, shared, source, work = sys.argv[1:5]
data = os.path.join(shared, "vhf-pelvis")
if not os.path.exists(os.path.join(data, "anterior_wall_of_uterus.obj")):
    print(f"skip: {data} does not hold the Visible Human meshes")
    sys.exit(77)
os.makedirs(work, exist_ok=True)

# The committed scene names the meshes relative to a checkout next to ../shared; point them here.
with open(os.path.join(source, "data", "vhf-pelvis", "left_adnexa.json")) as f:
    scene = json.load(f)
for part in scene["parts"]:
    if "mesh" in part:
        part["mesh"] = os.path.join(data, os.path.basename(part["mesh"]))
    if "meshes" in part:
        part["meshes"] = [os.path.join(data, os.path.basename(m)) for m in part["meshes"]]
scene_path = os.path.join(work, "left_adnexa.json")
with open(scene_path, "w") as f:
    json.dump(scene, f, indent=2)

series_dir = os.path.join(work, "series")
run = subprocess.run([demo, "--model", scene_path, "--seconds", "3", "--no-render", "--out",
                      os.path.join(work, "out"), "--export", series_dir, "--export-hz", "20"],
                     capture_output=True, text=True, timeout=600)
print(run.stdout)
assert run.returncode == 0, run.stderr
names = [p["name"] for p in scene["parts"]]
probed = next(line for line in run.stdout.splitlines() if line.startswith("session:"))
for name in names:  # each part of this model is probed, none of the bundled model's is asked for
    assert name in probed, (name, probed)
with open(os.path.join(work, "out", "stats.json")) as f:
    stats = json.load(f)
assert stats["peak_instrument_force_N"] > 0, stats

root = ET.parse(os.path.join(series_dir, "fsm.pvd")).getroot()
sets = root.findall("./Collection/DataSet")
times = sorted({float(d.get("timestep")) for d in sets})
# At most 20 Hz x 3 s = 60 states; the render thread writes them, and on a loaded machine (the test
# suite runs two at a time) it gets fewer frames: 28 were seen. Ten still make a series.
assert len(times) == stats["exported_states"] >= 10, (len(times), stats["exported_states"])
assert all(b > a for a, b in zip(times, times[1:]))
spheres = [d.get("file") for d in sets if d.get("part") == "0"]
surfaces = [d.get("file") for d in sets if d.get("part") == "1"]
assert len(spheres) == len(surfaces) == len(times)

first, last = (meshio.read(os.path.join(series_dir, spheres[k])) for k in (0, -1))
for m in (first, last):
    assert m.points.shape == (stats["spheres"], 3)
    blocks = {c.type: c.data for c in m.cells}
    assert len(blocks["line"]) == stats["links"]
    assert len(blocks["tetra"]) > 0
    assert blocks["line"].max() < stats["spheres"] and blocks["tetra"].max() < stats["spheres"]
    for key in ("velocity", "force"):
        assert m.point_data[key].shape == (stats["spheres"], 3)
        assert np.all(np.isfinite(m.point_data[key]))
    assert np.all(m.point_data["radius"] > 0)
np.testing.assert_array_equal(first.point_data["radius"], last.point_data["radius"])
# The tissue moved (gravity, the probe), and the fixed spheres did not.
fixed = last.point_data["fixed"] == 1
assert fixed.any() and np.abs(last.points[~fixed] - first.points[~fixed]).max() > 1e-4
np.testing.assert_allclose(last.points[fixed], first.points[fixed], atol=0)
surface = meshio.read(os.path.join(series_dir, surfaces[-1]))
assert surface.points.shape == (stats["surface_vertices"], 3)
assert set(np.unique(surface.cell_data["surface"][0])) == set(range(len(names)))
print(f"ok: {len(names)} parts probed, {len(times)} states, {stats['spheres']} spheres")
