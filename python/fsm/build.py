"""``fsm.build``: the model builder, provided by the separate ``fsm-builder`` distribution.

The builder links CGAL and is GPL-3.0-or-later, so it is not part of this (BSD-3-Clause) package:
install it beside ``fsm`` (``pip install --no-build-isolation python/builder`` from a source
checkout) and ``import fsm.build`` finds it. See ``fsm_builder`` for the functions.
"""

try:
    from fsm_builder import *  # noqa: F401,F403
    from fsm_builder import __all__  # noqa: F401
except ImportError as _e:  # pragma: no cover - depends on what is installed
    raise ImportError(
        "fsm.build needs the fsm-builder distribution (GPL-3.0-or-later, it links CGAL), which is "
        "installed separately from fsm: pip install --no-build-isolation python/builder"
    ) from _e
