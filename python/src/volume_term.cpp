// VolumeTerm: the optional per-tetrahedron volume penalty (quasi-incompressibility), applied as an
// external force each step. add_forces() writes into the caller's array in place.

#include "fsm/volume_term.hpp"
#include "common.hpp"

namespace fsm::python {

void define_volume_term(py::module_& m) {
  using VT = VolumeTerm<Scalar>;
  py::class_<VT>(m, "VolumeTerm",
                 R"(A volume-preserving penalty per tetrahedron (docs/validation.md).

VolumeTerm(tetrahedra, rest_positions, bulk_modulus)
    tetrahedra: (T, 4) node indices; rest_positions: (V, 3) m; bulk_modulus: kappa (Pa) >= 0.

Energy kappa/2 (V - V0)^2 / V0 per tetrahedron; forces are its exact negative gradient (they sum
to zero with zero torque). It adds kappa to the bulk modulus of a Van Gelder network and nothing to
its shear modulus; VolumeTerm.bulk_modulus_for(E, nu) gives the kappa for Poisson's ratio nu.
Applied explicitly: each step, add its forces to sim.external_forces before sim.step(dt); the step
must then satisfy h * sqrt(omega_max_squared(masses)) < 2.

    vt = fsm.VolumeTerm(mesh.tetrahedra, model.rest_positions, fsm.VolumeTerm.bulk_modulus_for(13150, 0.45))
    sim.external_forces[:] = 0
    vt.add_forces(sim.model.positions, sim.external_forces)
    sim.step(5e-5)

fsm.Error for an index out of range, a repeated node, a non-finite position or a flat element.)")
      .def(py::init([](const TetrahedronArray& tets,
                       const py::array_t<Scalar, py::array::c_style | py::array::forcecast>& rest,
                       Scalar kappa) {
             if (rest.ndim() != 2 || rest.shape(1) != 3)
               throw Error("", "rest_positions", "must have shape (V, 3)");
             Positions<Scalar> x(rest.shape(0), 3);
             std::copy(rest.data(), rest.data() + rest.size(), x.data());
             return VT(tets, x, kappa);
           }),
           py::arg("tetrahedra"), py::arg("rest_positions"), py::arg("bulk_modulus"),
           "Holds the tetrahedra and their rest volumes.")
      .def_static(
          "bulk_modulus_for", &VT::bulk_modulus_for, py::arg("youngs_modulus"), py::arg("poisson"),
          "kappa (Pa) giving a network of modulus E (Pa) the Poisson's ratio nu in [0.25, 0.5).")
      .def_property_readonly("num_tetrahedra", &VT::num_tetrahedra, "|T|")
      .def_property_readonly("num_nodes", &VT::num_nodes, "|V| the term was made for")
      .def_property("bulk_modulus", &VT::bulk_modulus, &VT::set_bulk_modulus, "kappa (Pa)")
      .def_property_readonly(
          "rest_volumes",
          [](const VT& v) { return Eigen::VectorXd(v.rest_volumes().template cast<double>()); },
          "signed rest volumes (m^3), a copy")
      .def(
          "energy",
          [](const VT& v, const py::array_t<Scalar, py::array::c_style | py::array::forcecast>& x) {
            if (x.ndim() != 2 || x.shape(0) != v.num_nodes() || x.shape(1) != 3)
              throw Error("", "positions",
                          "must have shape (" + std::to_string(v.num_nodes()) + ", 3)");
            Eigen::Map<const Positions<Scalar>> xm(x.data(), x.shape(0), 3);
            return v.energy(xm);
          },
          py::arg("positions"), "Energy (J) at positions (V, 3) m.")
      .def(
          "add_forces",
          [](const VT& v, const py::array_t<Scalar, py::array::c_style | py::array::forcecast>& x,
             py::array f) {
            if (x.ndim() != 2 || x.shape(0) != v.num_nodes() || x.shape(1) != 3)
              throw Error("", "positions",
                          "must have shape (" + std::to_string(v.num_nodes()) + ", 3)");
            if (!py::isinstance<py::array_t<Scalar>>(f) || f.ndim() != 2 ||
                f.shape(0) != v.num_nodes() || f.shape(1) != 3 ||
                !(f.flags() & py::array::c_style) || !f.writeable())
              throw Error("", "forces",
                          "must be a writeable, C-contiguous float64 array of shape (" +
                              std::to_string(v.num_nodes()) +
                              ", 3) (e.g. Simulation.external_forces)");
            Eigen::Map<const Positions<Scalar>> xm(x.data(), x.shape(0), 3);
            Eigen::Map<Positions<Scalar>> fm(static_cast<Scalar*>(f.mutable_data()), f.shape(0), 3);
            v.add_forces(xm, fm);
          },
          py::arg("positions"), py::arg("forces"),
          "Adds the term's forces (N) into `forces`, in place.")
      .def(
          "omega_max_squared",
          [](const VT& v, const Eigen::VectorXd& masses,
             const Eigen::Matrix<std::uint8_t, Eigen::Dynamic, 1>& fixed) {
            ScalarArray<Scalar> mm = masses.cast<Scalar>();
            return v.omega_max_squared(mm, fixed);
          },
          py::arg("masses"), py::arg("fixed"),
          "Bound on the squared highest angular frequency (rad^2/s^2) of the term alone (masses "
          "kg, fixed 0/1).");
}

}  // namespace fsm::python
