"""ParaView output: simulation states as VTK XML files (``.vtu``) and a time series (``.pvd``).

Written through meshio (Debian's ``python3-meshio``), in the same layout as the C++
``fsm::VtkSeriesWriter`` that ``fsm-demo --export DIR`` uses:

* spheres as points with point data ``radius`` (m), ``velocity`` (m/s), ``force`` (N), ``fixed``
  and ``region``; links as ``line`` cells and tetrahedra as ``tetra`` cells, with cell data
  ``kind`` (0 link, 1 tetrahedron);
* the render surface (a TissueModel's skin) as ``triangle`` cells, cell data ``surface`` (the index
  of the part's surface in ``Skin.surfaces``);
* ``NAME.pvd`` lists both pieces per state (part 0 spheres, part 1 surface) with its time, and is
  rewritten after every state, so a series cut short still opens in ParaView.

Example::

    series = fsm.export.VtkSeries("out", tissue_model)
    for k in range(100):
        sim.step(1e-3)
        series.write(sim.time, sim.model.positions, sim.model.velocities, sim.internal_forces(),
                     surface=tissue_model.skin.evaluate(sim.model.positions))
"""

import math
import os

import numpy as np

from ._fsm import Error

__all__ = ["sphere_mesh", "surface_mesh", "VtkSeries"]


def _meshio():
    try:
        import meshio
    except ImportError as e:  # pragma: no cover - depends on the machine
        raise Error("fsm.export needs meshio (Debian: python3-meshio)") from e
    return meshio


def _rows(name, array, n):
    a = np.asarray(array, dtype=np.float64)
    if a.shape != (n, 3):
        raise Error(f"{name}: must be an ({n}, 3) array, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise Error(f"{name}: holds NaN or inf")
    return a


def sphere_mesh(model, positions=None, velocities=None, forces=None):
    """The spheres of ``model`` (a SphereModel or TissueModel) as a ``meshio.Mesh``.

    positions / velocities / forces default to the model's own positions, velocities and zeros.
    """
    meshio = _meshio()
    m = getattr(model, "spheres", model)
    n = m.num_nodes
    x = _rows("positions", m.positions if positions is None else positions, n)
    v = _rows("velocities", m.velocities if velocities is None else velocities, n)
    f = _rows("forces", np.zeros((n, 3)) if forces is None else forces, n)
    cells = [("line", np.asarray(m.links, dtype=np.int32))]
    kind = [np.zeros(m.num_links, dtype=np.int32)]
    if m.num_tetrahedra > 0:
        cells.append(("tetra", np.asarray(m.tetrahedra, dtype=np.int32)))
        kind.append(np.ones(m.num_tetrahedra, dtype=np.int32))
    point_data = {
        "radius": np.asarray(m.radii, dtype=np.float64).copy(),
        "velocity": v,
        "force": f,
        "fixed": np.asarray(m.fixed, dtype=np.int32),
        "region": np.asarray(m.node_regions, dtype=np.int32),
    }
    return meshio.Mesh(x, cells, point_data=point_data, cell_data={"kind": kind})


def surface_mesh(skin, vertices=None):
    """The render surface of a Skin (``TissueModel.skin``) as a ``meshio.Mesh``: the rest surface,
    or ``vertices`` (|S| x 3, e.g. ``skin.evaluate(positions)``)."""
    meshio = _meshio()
    x = _rows("surface", skin.vertices if vertices is None else vertices, skin.num_vertices)
    faces = np.asarray(skin.faces, dtype=np.int32)
    which = np.full(len(faces), -1, dtype=np.int32)
    for k, s in enumerate(skin.surfaces):
        which[s.first_face : s.first_face + s.num_faces] = k
    return meshio.Mesh(x, [("triangle", faces)], cell_data={"surface": [which]})


class VtkSeries:
    """Writes states of one model into ``directory`` as a ParaView time series (``NAME.pvd``).

    ``model`` is a SphereModel or a TissueModel; with a TissueModel (or ``skin=``) each state also
    gets the render surface. fsm.Error for a bad name, a time that does not increase, or arrays of
    the wrong shape.
    """

    def __init__(self, directory, model, skin=None, name="fsm"):
        if not name or "/" in name or "\\" in name:
            raise Error(f"VtkSeries: the series name {name!r} is empty or a path")
        self.directory = os.fspath(directory)
        self.model = model
        self.skin = skin if skin is not None else getattr(model, "skin", None)
        if self.skin is not None and self.skin.num_vertices == 0:
            self.skin = None
        self.name = name
        self.times = []
        os.makedirs(self.directory, exist_ok=True)

    @property
    def series_path(self):
        return os.path.join(self.directory, self.name + ".pvd")

    def _file(self, piece, k):
        return f"{self.name}_{piece}_{k:06d}.vtu"

    def write(self, time, positions=None, velocities=None, forces=None, surface=None):
        """Writes one state at ``time`` (s); see sphere_mesh and surface_mesh for the arrays."""
        meshio = _meshio()
        time = float(time)
        if not math.isfinite(time) or (self.times and not time > self.times[-1]):
            raise Error(f"VtkSeries: time {time} must be finite and after {self.times[-1:]}")
        k = len(self.times)
        mesh = sphere_mesh(self.model, positions, velocities, forces)
        meshio.write(os.path.join(self.directory, self._file("spheres", k)), mesh,
                     file_format="vtu", binary=True, compression=None)
        if self.skin is not None:
            meshio.write(os.path.join(self.directory, self._file("surface", k)),
                         surface_mesh(self.skin, surface), file_format="vtu", binary=True,
                         compression=None)
        self.times.append(time)
        self._write_index()

    def _write_index(self):
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        for k, t in enumerate(self.times):
            lines.append(f'    <DataSet timestep="{t!r}" part="0" file="{self._file("spheres", k)}"/>')
            if self.skin is not None:
                lines.append(f'    <DataSet timestep="{t!r}" part="1" '
                             f'file="{self._file("surface", k)}"/>')
        lines += ["  </Collection>", "</VTKFile>", ""]
        with open(self.series_path, "w") as f:
            f.write("\n".join(lines))
