"""VolumeTerm bindings: forces are the exact negative gradient, sum to zero, written in place."""

import numpy as np
import pytest

import fsm


def test_volume_term_forces_are_the_gradient_and_balance():
    mesh = fsm.make_cube_lattice((0, 0, 0), (2, 2, 2), 0.005)
    x0 = np.array(mesh.vertices)
    vt = fsm.VolumeTerm(mesh.tetrahedra, x0, fsm.VolumeTerm.bulk_modulus_for(13150.0, 0.45))
    assert vt.num_nodes == len(x0) and vt.num_tetrahedra == len(mesh.tetrahedra)
    assert vt.bulk_modulus > 0
    rng = np.random.default_rng(1)
    x = x0 + rng.normal(0, 2e-4, x0.shape)
    f = np.zeros_like(x)
    vt.add_forces(x, f)
    assert np.abs(f.sum(axis=0)).max() < 1e-9 * np.abs(f).max()  # equal and opposite
    assert vt.energy(x0) == pytest.approx(0.0, abs=1e-18)
    # Central differences of the energy along a few coordinates.
    h = 1e-8
    for i, c in [(3, 0), (10, 2), (20, 1)]:
        xp, xm = x.copy(), x.copy()
        xp[i, c] += h
        xm[i, c] -= h
        g = (vt.energy(xp) - vt.energy(xm)) / (2 * h)
        assert f[i, c] == pytest.approx(-g, rel=1e-4, abs=1e-9)
    with pytest.raises(fsm.Error):
        vt.add_forces(x, np.zeros((3, 3)))
    with pytest.raises(fsm.Error):
        fsm.VolumeTerm(np.array([[0, 0, 1, 2]]), x0, 1000.0)  # repeated node
