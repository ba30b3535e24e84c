"""libfsm: filled-sphere soft-tissue simulation for surgical training.

A thin package over the compiled extension ``fsm._fsm``. Units are SI throughout (m, kg, s, N,
Pa). Arrays are numpy views of the C++ state (row-major, ``|V| x 3`` for positions).

Quick start::

    import fsm
    tissue = fsm.Material(density=1050, youngs_modulus=13150, viscosity=10.26)
    model = fsm.SphereModel()
    region = model.add_region("sample", tissue)
    fsm.add_tetrahedral_part(model, fsm.make_cube_lattice((0, 0, 0), (10, 10, 5), 0.002),
                             region, 0.001)
    sim = fsm.Simulation(model, integrator="implicit_euler")
    sim.external_forces[42] = (0, 0, -0.05)
    sim.step(1e-3)
    print(sim.model.positions[42])
"""

from ._fsm import (  # noqa: F401
    Blade,
    CapsuleShape,
    ContactOptions,
    ContactSolver,
    ConvexHullShape,
    CutSurface,
    CylinderShape,
    DeviceLimits,
    DeviceState,
    EnergyReport,
    Error,
    ForceLaw,
    GraspEvent,
    Grasper,
    GrasperOptions,
    HapticDevice,
    HeunIntegrator,
    ImplicitEulerIntegrator,
    ImprovedEulerIntegrator,
    Instrument,
    Integrator,
    Material,
    Part,
    PartRange,
    Pose,
    RayHit,
    Region,
    ScriptedHapticDevice,
    ServoLoop,
    ServoOptions,
    ServoStats,
    Simulation,
    Skin,
    SkinSurface,
    SpectralBound,
    SphereModel,
    SphereShape,
    StepReport,
    SymplecticEulerIntegrator,
    TetrahedralMesh,
    TissueModel,
    TopologyChange,
    Topology,
    TriangleBvh,
    VoigtLink,
    VolumeTerm,
    Waypoint,
    Wrench,
    add_tetrahedral_part,
    closest_point_on_triangle,
    device_names,
    integrator_names,
    intersect_ray_triangle,
    load_model,
    make_cube_lattice,
    make_device,
    make_integrator,
    rod_link,
    save_model,
    shape_contact,
    spectral_bound,
    tetrahedral_link,
    __version__,
)

__all__ = [name for name in dir() if not name.startswith("_")]
