"""Collision from Python: shapes, poses, the contact solver writing into the simulation's forces,
and the triangle tree."""
import math

import numpy as np
import pytest

import fsm

TOP = 0.010  # the block fixture's top layer (m): 2 cells of 5 mm


def pressing_tool(depth, radius=0.003):
    """A ball over the middle of the block fixture's top whose surface dips `depth` (m) below the
    top spheres' centres (a tetrahedral filling's surface: its vertices meet instruments at their
    centres)."""
    centre = (0.01, 0.01, TOP + radius - depth)
    return fsm.Instrument(fsm.SphereShape(radius), fsm.Pose(centre), name="probe", friction=0.0)


def test_pressed_sphere_forces_are_equal_and_opposite_to_the_wrench(block):
    solver = fsm.ContactSolver(block)
    k = solver.add_instrument(pressing_tool(0.001))
    forces = np.zeros((block.num_nodes, 3))
    assert solver.compute(block, forces) == solver.num_contacts > 0
    w = solver.wrench(k)
    # Newton's third law: what the tool pushes into the spheres is what the spheres push back.
    # Tolerance: a sum of a few terms of ~0.1 N in double precision.
    assert np.allclose(forces.sum(axis=0), -w.force, rtol=0, atol=1e-12)
    assert w.force[2] > 0 and forces[:, 2].sum() < 0  # the tool is pushed up, the tissue down
    # The record of contacts accounts for every force, and the torque about the pose origin.
    c = solver.contacts
    assert c.dtype.names == ("sphere", "instrument", "other", "normal", "depth", "point", "force")
    assert np.all(c["instrument"] == k) and np.all(c["other"] == -1) and np.all(c["depth"] > 0)
    assert np.allclose(np.linalg.norm(c["normal"], axis=1), 1.0, atol=1e-12)
    summed = np.zeros_like(forces)
    np.add.at(summed, c["sphere"], c["force"])
    assert np.array_equal(summed, forces)
    arm = c["point"] - solver.instrument(k).pose.position
    assert np.allclose(w.torque, -np.cross(arm, c["force"]).sum(axis=0), rtol=0, atol=1e-14)
    assert solver.candidates >= solver.narrow_tests >= solver.num_contacts
    # Deeper is harder (penalty force grows with depth); apart gives nothing.
    solver.instrument(k).pose.position[2] -= 0.0005
    solver.compute(block, np.zeros((block.num_nodes, 3)))
    assert solver.wrench(k).force[2] > w.force[2]
    solver.instrument(k).pose.position[2] += 0.01
    forces[:] = 0
    assert solver.compute(block, forces) == 0
    assert not forces.any() and not solver.wrench(k).force.any() and len(solver.contacts) == 0


def test_compute_writes_into_the_simulations_force_array_in_place(block):
    sim = fsm.Simulation(block)
    solver = fsm.ContactSolver(sim.model)
    solver.add_instrument(pressing_tool(0.001))
    f = sim.external_forces
    f[0] = (1.0, 2.0, 3.0)  # the user's own load stays: contact forces are added
    solver.compute(sim.model, f)
    fresh = sim.external_forces  # a new view of the same C++ array sees the contact forces
    assert np.shares_memory(f, fresh)
    assert fresh[:, 2].sum() < 3.0 and np.array_equal(fresh, f)
    assert np.array_equal(fresh[0], (1.0, 2.0, 3.0))
    before = solver.wrench(0).force.copy()
    # The overload taking the simulation hands the same contacts to its force model instead, for
    # the step to integrate: the external forces are left alone, the wrench is the same.
    assert solver.compute(sim) == solver.num_contacts > 0
    assert np.array_equal(sim.external_forces, f)
    assert np.allclose(solver.wrench(0).force, before, rtol=0, atol=1e-15)
    f[:] = 0
    assert sim.step(1e-3).advanced
    solver.collect(sim)  # the end-of-step forces: the block pushed back, the tool holds still
    assert 0 < solver.wrench(0).force[2]
    with pytest.raises(fsm.Error, match="collect"):
        solver.collect(fsm.Simulation(block))
    # Arrays the solver could only write into through a copy are refused, never silently copied.
    with pytest.raises(fsm.Error, match="float64"):
        solver.compute(sim.model, np.zeros((block.num_nodes, 3), dtype=np.float32))
    with pytest.raises(fsm.Error, match=r"has shape \(3, 3\), wanted \(%d, 3\)" % block.num_nodes):
        solver.compute(sim.model, np.zeros((3, 3)))
    with pytest.raises(fsm.Error, match="C-contiguous"):
        solver.compute(sim.model, np.zeros((3, block.num_nodes)).T)
    readonly = np.zeros((block.num_nodes, 3))
    readonly.flags.writeable = False
    with pytest.raises(fsm.Error, match="read-only"):
        solver.compute(sim.model, readonly)
    other = fsm.SphereModel()
    r = other.add_region("x", fsm.Material(youngs_modulus=1000.0))
    other.add_node((0, 0, 0), 0.001, 0.001, r)
    with pytest.raises(fsm.Error, match="sized for"):
        solver.compute(other, np.zeros((1, 3)))


def test_an_instrument_pressed_in_a_simulation_dents_the_block(block):
    sim = fsm.Simulation(block, gravity=(0, 0, 0))
    solver = fsm.ContactSolver(sim)
    tool = solver.add_instrument(pressing_tool(0.0))
    top = np.flatnonzero(np.isclose(sim.model.rest_positions[:, 2], TOP))
    for _ in range(200):  # 2 mm down over 0.2 s
        solver.instrument(tool).pose.position[2] -= 1e-5
        solver.instrument(tool).linear_velocity[:] = (0, 0, -0.01)
        assert solver.step(sim, 1e-3).status == "ok"
    dent = sim.model.rest_positions[top, 2] - sim.model.positions[top, 2]
    # The vertex under the tool went down with it, sliding a little off the frictionless ball's
    # apex, and stays on the ball's surface: stiff contact, penetration under 1% of the 2 mm stroke.
    c = solver.contacts
    assert len(c) >= 1 and dent.max() > 1.5e-3
    gap = np.linalg.norm(sim.model.positions[c["sphere"]] - solver.instrument(tool).pose.position,
                         axis=1) - 0.003
    assert np.all(np.abs(gap) < 2e-5)
    assert solver.wrench(tool).force[2] > 0
    assert np.allclose(c["force"].sum(axis=0), -solver.wrench(tool).force, atol=1e-12)
    assert not sim.external_forces.any()


def test_project_moves_spheres_out_of_the_instrument(block):
    model = block.copy()
    solver = fsm.ContactSolver(model)
    solver.add_instrument(pressing_tool(0.001))
    moved = solver.project(model)
    assert moved > 0
    solver.compute(model, np.zeros((model.num_nodes, 3)))
    assert solver.num_contacts == 0 or solver.contacts["depth"].max() < 1e-12


def test_bad_shapes_poses_and_options_raise_fsm_error(block):
    with pytest.raises(fsm.Error, match="SphereShape"):
        fsm.SphereShape(-0.001)
    with pytest.raises(fsm.Error, match="CapsuleShape"):
        fsm.CapsuleShape(0.001, float("nan"))
    with pytest.raises(fsm.Error, match="CylinderShape"):
        fsm.CylinderShape(float("inf"), 0.01)
    with pytest.raises(fsm.Error, match="edge_radius"):
        fsm.CylinderShape(0.003, 0.01, edge_radius=0.004)  # larger than the radius
    assert fsm.CylinderShape(0.003, 0.01, edge_radius=0.001).edge_radius == 0.001
    with pytest.raises(fsm.Error, match="ConvexHullShape"):
        fsm.ConvexHullShape(np.eye(3))  # three points
    with pytest.raises(fsm.Error, match="ConvexHullShape"):
        fsm.ConvexHullShape([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])  # one plane
    with pytest.raises(fsm.Error, match=r"has shape \(4, 2\), wanted \(n, 3\)"):
        fsm.ConvexHullShape(np.zeros((4, 2)))
    hull = fsm.ConvexHullShape([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    assert hull.points.shape == (4, 3)
    with pytest.raises(fsm.Error, match="quaternion"):
        fsm.Pose((0, 0, 0), (0, 0, 0, 0))
    with pytest.raises(fsm.Error, match="not a rotation"):
        fsm.Pose((0, 0, 0), np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(fsm.Error, match="wanted \\(4,\\) quaternion"):
        fsm.Pose((0, 0, 0), (1, 0, 0))
    solver = fsm.ContactSolver(block)
    shape = fsm.SphereShape(0.001)
    shape.radius = -1.0  # fields are plain data; the solver checks what it is given
    with pytest.raises(fsm.Error, match="instrument 'bad'"):
        solver.add_instrument(fsm.Instrument(shape, name="bad"))
    with pytest.raises(fsm.Error, match="friction"):
        solver.add_instrument(fsm.Instrument(fsm.SphereShape(0.001), friction=-1))
    with pytest.raises(fsm.Error, match="contact options"):
        fsm.ContactSolver(block, fsm.ContactOptions(stiffness_ratio=0))
    with pytest.raises(fsm.Error, match="detection_margin"):
        fsm.ContactSolver(block, fsm.ContactOptions(detection_margin=-0.1))
    assert fsm.ContactOptions().detection_margin == 0.25
    with pytest.raises(IndexError):
        solver.instrument(0)
    with pytest.raises(TypeError):
        fsm.Instrument("not a shape")


def test_pose_orientation_from_quaternion_or_matrix():
    half = math.sqrt(0.5)
    p = fsm.Pose((1.0, 2.0, 3.0), (2 * half, 0, 0, 2 * half))  # 90 deg about z, normalised here
    assert np.allclose(p.orientation, (half, 0, 0, half), atol=1e-15)
    assert np.allclose(p.to_world((1, 0, 0)), (1, 3, 3), atol=1e-15)
    assert np.allclose(p.to_local(p.to_world((0.3, -0.2, 0.1))), (0.3, -0.2, 0.1), atol=1e-15)
    R = p.rotation
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-15)
    q = fsm.Pose(p.position, R)
    assert np.allclose(q.orientation, p.orientation, atol=1e-15)
    p.position[0] = 5.0  # a view
    assert p.to_world((0, 0, 0))[0] == 5.0
    ins = fsm.Instrument(fsm.CapsuleShape(0.002, 0.02), p, linear_velocity=(0, 0, -0.01))
    ins.pose.position[2] = -1.0
    ins.linear_velocity[2] = 0.5
    assert ins.pose.position[2] == -1.0 and ins.linear_velocity[2] == 0.5
    assert isinstance(ins.shape, fsm.CapsuleShape) and ins.shape.half_length == 0.02
    c = fsm.shape_contact(fsm.SphereShape(0.01), fsm.Pose(), (0, 0, 0.012), 0.005)
    assert c["depth"] == pytest.approx(0.003) and np.allclose(c["normal"], (0, 0, 1))
    assert fsm.shape_contact(fsm.SphereShape(0.01), fsm.Pose(), (0, 0, 0.02), 0.005) is None


def test_ray_cast_hits_a_known_triangle_and_refit_follows_the_surface():
    # A unit square in z = 0 as two triangles, and a far-away third one.
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [5, 5, 5], [6, 5, 5], [5, 6, 5]], float)
    f = np.array([[0, 1, 2], [1, 3, 2], [4, 5, 6]])
    bvh = fsm.TriangleBvh(v, f)
    assert bvh.num_faces == 3 and bvh.num_vertices == 7
    hit = bvh.ray_cast((0.25, 0.125, 1.0), (0, 0, -2.0))
    assert hit.face == 0
    assert hit.distance == pytest.approx(1.0, abs=1e-15)
    assert (hit.u, hit.v) == pytest.approx((0.25, 0.125), abs=1e-15)  # weights of vertices 1, 2
    assert bvh.ray_cast((0.75, 0.75, 1.0), (0, 0, -1)).face == 1
    assert bvh.ray_cast((0.25, 0.25, 1.0), (0, 0, 1)) is None  # pointing away
    assert bvh.ray_cast((0.25, 0.25, 1.0), (0, 0, -1), max_distance=0.5) is None
    near = bvh.faces_near((0.5, 0.5, 0.1), 0.2)
    assert near.dtype == np.int32 and sorted(near) == [0, 1]
    assert len(bvh.faces_near((3, 3, 3), 0.1)) == 0
    bvh.refit(v + (0, 0, 0.5))
    assert bvh.ray_cast((0.25, 0.125, 1.0), (0, 0, -1)).distance == pytest.approx(0.5)
    with pytest.raises(fsm.Error, match=r"wanted \(7, 3\)"):
        bvh.refit(v[:3])
    with pytest.raises(fsm.Error, match="face"):
        fsm.TriangleBvh(v, [[0, 1, 99]])
    t = fsm.intersect_ray_triangle((0.25, 0.125, 1.0), (0, 0, -2.0), v[0], v[1], v[2])
    assert t.distance == pytest.approx(0.5) and t.face == -1
    assert np.allclose(fsm.closest_point_on_triangle((2, 2, 1), v[0], v[1], v[2]), (0.5, 0.5, 0))
