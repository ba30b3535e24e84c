"""SphereModel from Python: numpy views alias the C++ state, shapes and dtypes, errors."""
import numpy as np
import pytest

import fsm


def test_arrays_are_views_with_the_documented_shapes_and_dtypes(block):
    n, l = block.num_nodes, block.num_links
    expected = {
        "positions": ((n, 3), np.float64), "velocities": ((n, 3), np.float64),
        "rest_positions": ((n, 3), np.float64), "masses": ((n,), np.float64),
        "radii": ((n,), np.float64), "node_regions": ((n,), np.int32),
        "fixed": ((n,), np.uint8), "links": ((l, 2), np.int32),
        "rest_lengths": ((l,), np.float64), "stiffness": ((l,), np.float64),
        "damping": ((l,), np.float64), "large_stiffness": ((l,), np.float64),
        "switch_strain": ((l,), np.float64),
    }
    for name, (shape, dtype) in expected.items():
        a = getattr(block, name)
        assert a.shape == shape, name
        assert a.dtype == dtype, name
    # Row-major |V| x 3, and two reads share memory (a view, not a copy).
    assert block.positions.flags["C_CONTIGUOUS"]
    assert np.shares_memory(block.positions, block.positions)


def test_writing_a_view_changes_the_model(block):
    p = block.positions
    p[3] = (1.0, 2.0, 3.0)
    assert tuple(block.positions[3]) == (1.0, 2.0, 3.0)
    block.reset_to_rest()  # C++ writes, the old view sees it
    assert np.array_equal(p[3], block.rest_positions[3])
    block.masses[0] = -1.0
    with pytest.raises(fsm.Error, match=r"node 0 \(region 'block'\).*mass"):
        block.validate()


def test_whole_array_assignment_checks_the_shape(block):
    with pytest.raises(fsm.Error, match=r"positions.*shape \(2, 3\), wanted \(%d, 3\)" % block.num_nodes):
        block.positions = np.zeros((2, 3))
    with pytest.raises(fsm.Error, match=r"masses.*wanted a vector of %d" % block.num_nodes):
        block.masses = np.ones(3)
    block.velocities = np.full((block.num_nodes, 3), 0.5)
    assert np.all(block.velocities == 0.5)


def test_bad_input_raises_fsm_error_naming_the_element(tissue):
    m = fsm.SphereModel()
    r = m.add_region("body", tissue)
    m.add_node((0, 0, 0), 0.001, 0.001, r)
    m.add_node((0.01, 0, 0), 0.001, 0.001, r)
    with pytest.raises(fsm.Error, match=r"node 2 \(region 'body'\): radius"):
        m.add_node((0, 0, 0), -1.0, 0.001, r)
    with pytest.raises(fsm.Error, match=r"link 0 \(nodes 1-1\): links a node to itself"):
        m.add_link(1, 1, 10.0)
    with pytest.raises(fsm.Error, match="youngs_modulus"):
        fsm.Material(youngs_modulus=-1.0)
    with pytest.raises(fsm.Error, match="region 'body'"):
        m.add_region("body", tissue)
    assert isinstance(fsm.Error("x"), RuntimeError)
    assert m.num_nodes == 2 and m.num_links == 0


def test_links_and_laws_round_trip(tissue):
    m = fsm.SphereModel()
    r = m.add_region("r", tissue)
    a = m.add_node((0, 0, 0), 0.001, 0.001, r)
    b = m.add_node((0.01, 0, 0), 0.001, 0.001, r)
    m.add_link(a, b, fsm.VoigtLink(0.01, 100.0, 0.5, large_stiffness=400.0, switch_strain=0.1))
    law = m.link(0)
    assert law.stiffness == 100.0 and law.large_stiffness == 400.0 and m.has_bilinear_links
    assert law.elastic_force(0.002) == pytest.approx(100 * 0.001 + 400 * 0.001)
    assert list(m.links[0]) == [0, 1]
    # Van Gelder from Python matches the formula.
    k = fsm.tetrahedral_link(tissue, 1e-6, 0.01)
    assert k.stiffness == pytest.approx(13150 * 1e-6 / 1e-4)


def test_lattice_with_a_python_shape_filter():
    ball = fsm.make_cube_lattice((-0.02, -0.02, -0.02), (8, 8, 8), 0.005,
                                 inside=lambda c: float(np.linalg.norm(c)) < 0.02)
    full = fsm.make_cube_lattice((-0.02, -0.02, -0.02), (8, 8, 8), 0.005)
    assert 0 < ball.volume < full.volume
    assert ball.vertices.shape[1] == 3 and ball.tetrahedra.shape[1] == 4
