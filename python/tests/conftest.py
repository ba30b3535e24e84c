import numpy as np
import pytest

import fsm


@pytest.fixture
def tissue():
    return fsm.Material(density=1050.0, youngs_modulus=13150.0, viscosity=10.26)


@pytest.fixture
def block(tissue):
    """A 4 x 4 x 2-cell lattice block (5 mm cells) with its bottom layer fixed."""
    model = fsm.SphereModel()
    region = model.add_region("block", tissue)
    fsm.add_tetrahedral_part(model, fsm.make_cube_lattice((0, 0, 0), (4, 4, 2), 0.005), region, 0.0025)
    for i in np.flatnonzero(model.rest_positions[:, 2] < 1e-9):
        model.set_fixed(int(i))
    return model
