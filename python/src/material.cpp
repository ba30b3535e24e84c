// Material, VoigtLink and the link-constant rules.

#include "common.hpp"

namespace fsm::python {

void define_material(py::module_& m) {
  using M = Material<Scalar>;
  py::class_<M>(m, "Material", R"(A homogeneous Voigt material: sigma = E eps + eta d(eps)/dt.

All values SI. A bilinear material switches from youngs_modulus to large_strain_modulus at
|strain| = switch_strain (large_strain_modulus = 0 means linear). poisson_ratio is used by the
continuum law only (the link network has 1/4 whatever it says). tear_strain: the strain
(l - l0) / l0 past which the tissue tears (a link breaks, and in a continuum region the tetrahedra
that share it); infinity = never.)")
      .def(py::init([](Scalar density, Scalar youngs_modulus, Scalar viscosity,
                       Scalar large_strain_modulus, Scalar switch_strain, Scalar poisson_ratio,
                       Scalar tear_strain) {
             M mat{density,       youngs_modulus, viscosity,  large_strain_modulus,
                   switch_strain, poisson_ratio,  tear_strain};
             mat.validate("Material");
             return mat;
           }),
           py::arg("density") = 1000.0, py::arg("youngs_modulus"), py::arg("viscosity") = 0.0,
           py::arg("large_strain_modulus") = 0.0, py::arg("switch_strain") = 0.0,
           py::arg("poisson_ratio") = M{}.poisson_ratio, py::arg("tear_strain") = M{}.tear_strain,
           R"(density in kg/m^3, youngs_modulus in Pa, viscosity in Pa s; raises fsm.Error for
out-of-range values.)")
      .def_readwrite("density", &M::density, "kg/m^3")
      .def_readwrite("youngs_modulus", &M::youngs_modulus, "Pa (small-strain modulus)")
      .def_readwrite("viscosity", &M::viscosity, "Pa s")
      .def_readwrite("large_strain_modulus", &M::large_strain_modulus, "Pa (0: linear)")
      .def_readwrite("switch_strain", &M::switch_strain, "|strain| of the modulus switch")
      .def_readwrite("poisson_ratio", &M::poisson_ratio, "nu in (-1, 0.5), of the continuum law")
      .def_readwrite("tear_strain", &M::tear_strain, "strain past which it tears (inf: never)")
      .def_property_readonly("shear_modulus", &M::shear_modulus, "mu = E / (2 (1 + nu)) in Pa")
      .def_property_readonly("bulk_modulus", &M::bulk_modulus, "K = E / (3 (1 - 2 nu)) in Pa")
      .def_property_readonly("is_bilinear", &M::is_bilinear,
                             "True when large_strain_modulus > 0 (the modulus switches)")
      .def_property_readonly("retardation_time", &M::retardation_time, "eta / E in s")
      .def("__repr__", [](const M& mat) {
        return "Material(density=" + std::to_string(mat.density) +
               ", youngs_modulus=" + std::to_string(mat.youngs_modulus) +
               ", viscosity=" + std::to_string(mat.viscosity) +
               ", poisson_ratio=" + std::to_string(mat.poisson_ratio) +
               (mat.is_bilinear()
                    ? ", large_strain_modulus=" + std::to_string(mat.large_strain_modulus) +
                          ", switch_strain=" + std::to_string(mat.switch_strain)
                    : std::string()) +
               ")";
      });

  using L = VoigtLink<Scalar>;
  py::class_<L>(m, "VoigtLink",
                R"(One link's force law: spring and dashpot in parallel along the link.

rest_length in m, stiffness and large_stiffness in N/m, damping in N s/m, switch_strain
dimensionless (inf for a linear link).)")
      .def(py::init([](Scalar rest_length, Scalar stiffness, Scalar damping, py::object large,
                       py::object switch_strain) {
             if (large.is_none()) return L::linear(rest_length, stiffness, damping);
             return L::bilinear(rest_length, stiffness, damping, large.cast<Scalar>(),
                                switch_strain.cast<Scalar>());
           }),
           py::arg("rest_length"), py::arg("stiffness"), py::arg("damping") = 0.0,
           py::arg("large_stiffness") = py::none(), py::arg("switch_strain") = py::none())
      .def_readwrite("rest_length", &L::rest_length, "l0 (m)")
      .def_readwrite("stiffness", &L::stiffness, "small-strain spring constant (N/m)")
      .def_readwrite("damping", &L::damping, "dashpot constant (N s/m)")
      .def_readwrite("large_stiffness", &L::large_stiffness,
                     "spring constant beyond the switch strain (N/m)")
      .def_readwrite("switch_strain", &L::switch_strain,
                     "|strain| where the stiffness switches (inf: linear)")
      .def("elastic_force", &L::elastic_force, py::arg("extension"),
           "Elastic force (N) at an extension l - l0 (m); positive pulls the spheres together.")
      .def("energy", &L::energy, py::arg("extension"), "Elastic energy (J) at an extension (m).")
      .def(
          "force",
          [](const L& law, const Vector3<Scalar>& xi, const Vector3<Scalar>& xj,
             const Vector3<Scalar>& vi, const Vector3<Scalar>& vj, const std::string& damping) {
            return law.force(xi, xj, vi, vj,
                             damping == "full_relative_velocity"
                                 ? DampingModel::full_relative_velocity
                                 : DampingModel::along_link);
          },
          py::arg("xi"), py::arg("xj"), py::arg("vi"), py::arg("vj"),
          py::arg("damping") = "along_link", "Force (N) on sphere i; sphere j gets its negative.");

  m.def("tetrahedral_link", &tetrahedral_link<Scalar>, py::arg("material"),
        py::arg("incident_volume"), py::arg("rest_length"),
        R"(Van Gelder's rule for an edge of a tetrahedral mesh: k = E * sum(V_T) / l^2.)");
  m.def("rod_link", &rod_link<Scalar>, py::arg("material"), py::arg("area"), py::arg("rest_length"),
        R"(A bar of cross-section area A (m^2): k = E A / l.)");
}

}  // namespace fsm::python
