// Tetrahedral meshes, lattices and add_tetrahedral_part().

#include "common.hpp"

namespace fsm::python {

void define_tetrahedral_mesh(py::module_& m) {
  using Mesh = TetrahedralMesh<Scalar>;
  py::class_<Mesh>(m, "TetrahedralMesh",
                   R"(Vertices (|V| x 3, m) and tetrahedra (|T| x 4 indices).)")
      .def(py::init([](const Positions<Scalar>& vertices, const TetrahedronArray& tetrahedra) {
             return Mesh{vertices, tetrahedra};
           }),
           py::arg("vertices"), py::arg("tetrahedra"))
      .def_readwrite("vertices", &Mesh::vertices, "|V| x 3 vertex positions (m)")
      .def_readwrite("tetrahedra", &Mesh::tetrahedra, "|T| x 4 vertex indices")
      .def_property_readonly("volume", &Mesh::volume, "m^3")
      .def("validate", &Mesh::validate, py::arg("what") = "mesh",
           "Raises fsm.Error naming `what` and the first bad vertex or tetrahedron.");

  m.def(
      "make_cube_lattice",
      [](const Vector3<Scalar>& origin, const Eigen::Vector3i& cells, Scalar spacing,
         py::object inside) {
        if (inside.is_none()) return make_cube_lattice(origin, cells, spacing);
        return make_cube_lattice(origin, cells, spacing, [&](const Vector3<Scalar>& centre) {
          return inside(centre).cast<bool>();
        });
      },
      py::arg("origin"), py::arg("cells"), py::arg("spacing"), py::arg("inside") = py::none(),
      R"(The Freudenthal lattice of a box of cells (nx, ny, nz) cubes of edge spacing (m): six
tetrahedra per cube. inside, if given, is called with each cube's centre (a length-3 array) and
keeps the cube when it returns True.)");

  py::class_<PartRange>(m, "PartRange", "Where a part's nodes and links landed in the model.")
      .def_readonly("first_node", &PartRange::first_node, "index of the part's first node")
      .def_readonly("num_nodes", &PartRange::num_nodes, "how many nodes it added")
      .def_readonly("first_link", &PartRange::first_link, "index of the part's first link")
      .def_readonly("num_links", &PartRange::num_links, "how many links it added")
      .def_readonly("first_tetrahedron", &PartRange::first_tetrahedron,
                    "index of the part's first tetrahedron")
      .def_readonly("num_tetrahedra", &PartRange::num_tetrahedra, "how many tetrahedra it added");

  m.def("add_tetrahedral_part", &add_tetrahedral_part<Scalar>, py::arg("model"), py::arg("mesh"),
        py::arg("region"), py::arg("radius"),
        R"(Adds a tetrahedral filling as nodes of a region: one sphere per vertex (radius in m), one
link per edge with Van Gelder's stiffness, lumped masses. Raises fsm.Error for a bad mesh.)");
}

}  // namespace fsm::python
