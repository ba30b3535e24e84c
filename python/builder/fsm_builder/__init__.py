"""libfsm's model builder (GPL-3.0-or-later: it links CGAL), the ``fsm-builder`` distribution.

A separate distribution and extension from the runtime (``fsm``, BSD-3-Clause), so that what a
vendor installs with ``fsm`` contains no GPL code. Use it as ``fsm.build`` (a thin alias in the
runtime package) or as ``fsm_builder``:

    import fsm, fsm.build
    model, report, table = fsm.build.build_model("data/uterus/uterus.json")
    print(table)
    fsm.save_model("uterus.fsm", model)
"""

import json as _json

from ._fsm_build import build_model as _build_model
from ._fsm_build import inspect_mesh, read_mesh, write_uterus_scene  # noqa: F401


def build_model(scene):
    """Builds a scene file (docs/scene.md).

    Returns ``(model, report, table)``: the :class:`fsm.TissueModel`, the build report as a dict
    (fields in docs/builder.md) and the Table-1-like text table. Raises :class:`fsm.Error` naming
    the file, the part and the reason for bad input.
    """
    model, report_json, table = _build_model(str(scene))
    return model, _json.loads(report_json), table


__all__ = ["build_model", "inspect_mesh", "read_mesh", "write_uterus_scene"]
