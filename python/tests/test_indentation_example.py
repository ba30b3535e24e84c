"""The indentation example (examples/python/indentation.py) with the continuum law: the flat punch's
force rises monotonically to 2.5 mm and no tetrahedron inverts, where the link network's falls."""
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "examples", "python"))
import indentation  # noqa: E402


def test_continuum_punch_rises_monotonically_without_inversion():
    r = indentation.indent(spacing=0.002, speed=2.5e-3, law="continuum", nu=0.45)
    d, f = r["displacement"], r["force"]
    assert d[-1] >= 2.5e-3 - 1e-9
    assert np.all(np.diff(f) > 0), "the force must rise at every sample"
    assert r["inverted"] == 0
    # Stiffer than the link network at 2.5 mm (which softens and collapses under the punch).
    links = indentation.indent(spacing=0.002, speed=2.5e-3, law="links")
    assert f[-1] > links["force"][-1]
