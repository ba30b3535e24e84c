// SphereModel: structure-of-arrays data, seen from numpy as views (no copies).

#include <cstddef>
#include <type_traits>

#include "common.hpp"

namespace fsm::python {

namespace {
using Model = SphereModel<Scalar>;

// A read-write property that is a numpy view of a |V| x 3 or |L| array of the model.
template <typename Get>
void rows3_property(py::class_<Model>& c, const char* name, Get get, const char* doc) {
  c.def_property(
      name,
      [get](py::object self) {
        Model& m = self.cast<Model&>();
        auto a = get(m);
        return view(a.data(), py::ssize_t(a.rows()), 3, self);
      },
      [get, name](Model& m,
                  const py::array_t<Scalar, py::array::c_style | py::array::forcecast>& v) {
        assign_rows3(get(m), v, name);
      },
      doc);
}

// A property viewing a |V| or |L| column: writable values, or (`check` given) a read-only view of
// structure whose setter validates every entry first (`check(model, value, index)` throws).
template <typename T, typename Get, typename Check = std::nullptr_t>
void column_property(py::class_<Model>& c, const char* name, Get get, const char* doc,
                     Check check = nullptr) {
  constexpr bool structural = !std::is_same_v<Check, std::nullptr_t>;
  c.def_property(
      name,
      [get](py::object self) {
        Model& m = self.cast<Model&>();
        auto a = get(m);
        return view<T>(a.data(), py::ssize_t(a.rows()), 0, self, structural);
      },
      [get, name, check](Model& m,
                         const py::array_t<T, py::array::c_style | py::array::forcecast>& v) {
        auto a = get(m);
        if (v.ndim() != 1 || v.shape(0) != py::ssize_t(a.rows()))
          throw Error("", name,
                      "has " + std::to_string(v.ndim()) + " dimensions and " +
                          std::to_string(v.ndim() ? v.shape(0) : 0) +
                          " entries, wanted a vector of " + std::to_string(a.rows()));
        if constexpr (structural)
          for (Index i = 0; i < Index(a.rows()); ++i) check(m, v.data()[i], i);
        std::copy(v.data(), v.data() + a.rows(), a.data());
      },
      doc);
}
}  // namespace

void define_sphere_model(py::module_& m) {
  py::enum_<ForceLaw>(m, "ForceLaw", R"(How a region's spheres resist deformation.

links: the paper's Voigt links (Poisson's ratio 1/4). continuum: neo-Hookean on the region's
tetrahedra with the material's Poisson's ratio (docs/physics.md section 11).)")
      .value("links", ForceLaw::links)
      .value("continuum", ForceLaw::continuum);
  py::class_<Region<Scalar>>(m, "Region", "A named part of a model with its material and law.")
      .def_readonly("name", &Region<Scalar>::name, "the region's name")
      .def_readonly("material", &Region<Scalar>::material, "its Material")
      .def_readonly("law", &Region<Scalar>::law, "its ForceLaw")
      .def("__repr__", [](const Region<Scalar>& r) { return "Region('" + r.name + "')"; });

  py::class_<Model> c(m, "SphereModel", R"(Spheres joined by Voigt links, grouped into regions.

Node arrays (|V| rows): positions, velocities, rest_positions (|V| x 3, m and m/s), masses (kg),
radii (m), node_regions, fixed (1 = fixed). Link arrays (|L| rows): links (|L| x 2 node indices),
rest_lengths (m), stiffness (N/m), damping (N s/m), large_stiffness (N/m), switch_strain.

Every array property is a numpy *view* of the model's memory: writing into it changes the model.
Views are invalidated by add_node/add_link (take a fresh one after growing the model). After
writing masses, fixed flags or link constants in place, call Simulation.refresh().)");
  c.def(py::init<>())
      .def("add_region", &Model::add_region, py::arg("name"), py::arg("material"),
           py::arg("law") = ForceLaw::links,
           "Adds a region; returns its index. Raises fsm.Error for a taken name or a bad material.")
      .def("set_region_law", &Model::set_region_law, py::arg("region"), py::arg("law"),
           "Sets a region's ForceLaw (the continuum law needs the region's nodes in tetrahedra).")
      .def("set_region_material", &Model::set_region_material, py::arg("region"),
           py::arg("material"),
           "Replaces a region's Material (links keep their constants: the continuum law and "
           "contacts follow the new one).")
      .def("add_tetrahedron", &Model::add_tetrahedron, py::arg("a"), py::arg("b"), py::arg("c"),
           py::arg("d"),
           "Adds a tetrahedron of four nodes of one region, positively oriented at rest; returns "
           "its index.")
      .def_property_readonly("num_tetrahedra", &Model::num_tetrahedra, "|T|")
      .def_property_readonly("has_continuum", &Model::has_continuum,
                             "True when some region uses the continuum law")
      .def("add_node", &Model::add_node, py::arg("rest_position"), py::arg("radius"),
           py::arg("mass"), py::arg("region"), "Adds a node at rest (m, m, kg); returns its index.")
      .def("add_link", py::overload_cast<Index, Index, Scalar, Scalar>(&Model::add_link),
           py::arg("i"), py::arg("j"), py::arg("stiffness"), py::arg("damping") = 0.0,
           "Adds a linear link whose rest length is the nodes' rest distance; returns its index.")
      .def("add_link", py::overload_cast<Index, Index, const VoigtLink<Scalar>&>(&Model::add_link),
           py::arg("i"), py::arg("j"), py::arg("law"), "Adds a link with a full VoigtLink law.")
      .def("set_fixed", &Model::set_fixed, py::arg("node"), py::arg("fixed") = true,
           "Marks a node fixed (or free); a fixed node is never integrated.")
      .def_property_readonly("num_nodes", &Model::num_nodes, "|V|, the number of spheres")
      .def_property_readonly("num_links", &Model::num_links, "|L|, the number of links")
      .def_property_readonly("num_regions", &Model::num_regions, "the number of regions")
      .def_property_readonly("num_fixed", &Model::num_fixed, "the number of fixed spheres")
      .def_property_readonly("regions", &Model::regions, "the Regions, a list (copies)")
      .def("region_index", &Model::region_index, py::arg("name"),
           "The index of the region of that name; fsm.Error if there is none.")
      .def("link", &Model::link, py::arg("index"), "Link l's VoigtLink (a copy).")
      .def("set_link", &Model::set_link, py::arg("index"), py::arg("law"),
           "Replaces link l's law with a VoigtLink; fsm.Error for a bad one.")
      .def_property_readonly("has_bilinear_links", &Model::has_bilinear_links,
                             "True when some link switches stiffness (bilinear material)")
      .def("reset_to_rest", &Model::reset_to_rest,
           "Positions back to rest positions, velocities to zero.")
      .def_property_readonly("total_mass", &Model::total_mass, "kg")
      .def("distribute_region_mass", &Model::distribute_region_mass, py::arg("region"),
           py::arg("volume"), "Gives every node of the region rho V / N (V in m^3).")
      .def("validate", &Model::validate,
           "Raises fsm.Error naming the first bad node, link or region.")
      .def(
          "copy", [](const Model& mm) { return Model(mm); }, "A deep copy.")
      .def("__repr__", [](const Model& mm) {
        return "SphereModel(" + std::to_string(mm.num_nodes()) + " spheres, " +
               std::to_string(mm.num_links()) + " links, " + std::to_string(mm.num_regions()) +
               " regions)";
      });
  rows3_property(
      c, "positions", [](Model& mm) { return mm.positions(); }, "|V| x 3, m");
  rows3_property(
      c, "velocities", [](Model& mm) { return mm.velocities(); }, "|V| x 3, m/s");
  rows3_property(
      c, "rest_positions", [](Model& mm) { return mm.rest_positions(); }, "|V| x 3, m");
  column_property<Scalar>(
      c, "masses", [](Model& mm) { return mm.masses(); }, "|V|, kg");
  column_property<Scalar>(
      c, "radii", [](Model& mm) { return mm.radii(); }, "|V|, m");
  column_property<Index>(
      c, "node_regions", [](Model& mm) { return mm.node_regions(); },
      "|V| region indices (a read-only view; assigning a whole array checks every index)",
      [](const Model& mm, Index r, Index i) {
        if (r < 0 || r >= mm.num_regions())
          throw Error("", "node_regions",
                      "entry " + std::to_string(i) + " is " + std::to_string(r) +
                          ", not a region in [0, " + std::to_string(mm.num_regions()) + ")");
      });
  column_property<std::uint8_t>(
      c, "fixed", [](Model& mm) { return mm.fixed(); },
      "|V|, 1 = fixed (a read-only view: use set_fixed, or Simulation.set_fixed in a "
      "simulation, which also zeroes the velocity)",
      [](const Model&, std::uint8_t f, Index i) {
        if (f > 1)
          throw Error("", "fixed",
                      "entry " + std::to_string(i) + " is " + std::to_string(int(f)) +
                          "; a fixed flag is 0 or 1");
      });
  column_property<Scalar>(
      c, "rest_lengths", [](Model& mm) { return mm.rest_lengths(); }, "|L|, m");
  column_property<Scalar>(
      c, "stiffness", [](Model& mm) { return mm.stiffness(); }, "|L|, N/m");
  column_property<Scalar>(
      c, "damping", [](Model& mm) { return mm.damping(); }, "|L|, N s/m");
  column_property<Scalar>(
      c, "large_stiffness", [](Model& mm) { return mm.large_stiffness(); }, "|L|, N/m");
  column_property<Scalar>(
      c, "switch_strain", [](Model& mm) { return mm.switch_strain(); }, "|L|, inf = linear");
  column_property<Scalar>(
      c, "tear_strain", [](Model& mm) { return mm.tear_strain(); },
      "|L|, each link's own tear strain (it tears past the smallest of this and its regions' "
      "materials'); inf = the materials decide. Simulation.refresh() after editing it.");
  c.def_property_readonly(
      "link_intact",
      [](py::object self) {
        Model& mm = self.cast<Model&>();
        return view<std::uint8_t>(mm.link_intact().data(), mm.num_links(), 0, self, true);
      },
      "|L|, 1 = holds, 0 = cut or torn (a read-only view)");
  c.def_property_readonly(
      "tetrahedron_intact",
      [](py::object self) {
        Model& mm = self.cast<Model&>();
        return view<std::uint8_t>(mm.tetrahedron_intact().data(), mm.num_tetrahedra(), 0, self,
                                  true);
      },
      "|T|, 1 = holds, 0 = cut or torn (a read-only view)");
  c.def_property_readonly("num_broken_links", &Model::num_broken_links, "links cut or torn so far");
  c.def_property_readonly("num_removed_tetrahedra", &Model::num_removed_tetrahedra,
                          "tetrahedra cut or torn so far");
  c.def("restore_topology", &Model::restore_topology,
        "Makes every link and tetrahedron whole again (Simulation.refresh() after).");
  c.def_property_readonly(
      "links",
      [](py::object self) {
        Model& mm = self.cast<Model&>();
        return view<Index>(mm.links().data(), mm.num_links(), 2, self, true);
      },
      "|L| x 2 node indices (int32), a read-only view (links change through add_link)");
  c.def_property_readonly(
      "tetrahedra",
      [](py::object self) {
        Model& mm = self.cast<Model&>();
        return view<Index>(const_cast<Index*>(mm.tetrahedra().data()), mm.num_tetrahedra(), 4, self,
                           true);
      },
      "|T| x 4 node indices (int32), a read-only view (add_tetrahedron adds one)");
}

}  // namespace fsm::python
