// TissueModel, Part, Skin and the model file.

#include "common.hpp"

namespace fsm::python {

void define_tissue_model(py::module_& m) {
  py::enum_<Topology>(m, "Topology", "How a part was filled with spheres.")
      .value("tetrahedral", Topology::tetrahedral)
      .value("axis", Topology::axis)
      .value("grid", Topology::grid)
      .value("packing", Topology::packing);

  py::class_<Part>(m, "Part", "One part of a built model: its spheres, links and render surface.")
      .def_readonly("name", &Part::name, "the part's name in the scene")
      .def_readonly("topology", &Part::topology, "how it was filled (a Topology)")
      .def_readonly("region", &Part::region, "its region index in the SphereModel")
      .def_readonly("radius", &Part::radius, "nominal sphere radius (m)")
      .def_readonly("first_node", &Part::first_node, "index of its first sphere")
      .def_readonly("num_nodes", &Part::num_nodes, "how many spheres it has")
      .def_readonly("first_link", &Part::first_link, "index of its first link")
      .def_readonly("num_links", &Part::num_links, "how many links it has")
      .def_readonly("surface", &Part::surface, "index into Skin.surfaces, or -1")
      .def_readonly("first_tetrahedron", &Part::first_tetrahedron,
                    "its first row in spheres.tetrahedra (tetrahedral parts)")
      .def_readonly("num_tetrahedra", &Part::num_tetrahedra,
                    "how many tetrahedra it has (0 for other topologies)")
      .def_property_readonly(
          "nodes",
          [](const Part& p) { return py::slice(p.first_node, p.first_node + p.num_nodes, 1); },
          "A slice selecting the part's spheres in the model's node arrays.")
      .def("__repr__", [](const Part& p) {
        return "Part('" + p.name + "', " + to_string(p.topology) + ", " +
               std::to_string(p.num_nodes) + " spheres)";
      });

  using S = Skin<Scalar>;
  py::class_<typename S::Surface>(m, "SkinSurface", "One part's render surface within the skin.")
      .def_readonly("name", &S::Surface::name, "the part's name")
      .def_readonly("first_vertex", &S::Surface::first_vertex, "its first row in Skin.vertices")
      .def_readonly("num_vertices", &S::Surface::num_vertices, "how many vertices")
      .def_readonly("first_face", &S::Surface::first_face, "its first row in Skin.faces")
      .def_readonly("num_faces", &S::Surface::num_faces, "how many faces");
  py::class_<S>(m, "Skin", R"(Render surfaces bound to the spheres.

vertices (|S| x 3, m) and faces (|F| x 3) are the rest surface (views); evaluate(positions) gives the
deformed vertices for sphere positions (|V| x 3).)")
      .def_property_readonly(
          "vertices",
          [](py::object self) {
            S& s = self.cast<S&>();
            return view(s.rest.vertices.data(), py::ssize_t(s.rest.vertices.rows()), 3, self);
          },
          "rest vertices |S| x 3 (m), a view")
      .def_property_readonly(
          "faces",
          [](py::object self) {
            S& s = self.cast<S&>();
            return view<Index>(s.rest.faces.data(), py::ssize_t(s.rest.faces.rows()), 3, self,
                               true);
          },
          "faces |F| x 3 (int32), a read-only view")
      .def_readonly("surfaces", &S::surfaces, "the SkinSurfaces, one per part with a surface")
      .def_property_readonly("num_vertices", &S::num_vertices, "|S|, render vertices in all")
      .def(
          "evaluate",
          [](const S& s, const py::array_t<Scalar, py::array::c_style | py::array::forcecast>& x) {
            if (x.ndim() != 2 || x.shape(1) != 3)
              throw Error("", "positions", "must be an (n, 3) array");
            const Eigen::Map<const Positions<Scalar>> X(x.data(), x.shape(0), 3);
            if (s.chain_nodes.size() && s.chain_nodes.maxCoeff() >= X.rows())
              throw Error("", "positions", "has fewer rows than the skin's spheres");
            if (s.nodes.size() && s.nodes.maxCoeff() >= X.rows())
              throw Error("", "positions", "has fewer rows than the skin's spheres");
            require_finite(X, "positions");
            Positions<Scalar> out(s.num_vertices(), 3);
            auto ws = s.make_workspace();
            {
              py::gil_scoped_release release;
              s.evaluate(X, ws, out);
            }
            return out;
          },
          py::arg("positions"),
          "Deformed render vertices (|S| x 3, a new array) for sphere positions.");

  using T = TissueModel<Scalar>;
  py::class_<T>(m, "TissueModel", R"(A built model: spheres, parts, attachment links and the skin.

Load one with fsm.load_model(path) or build one with fsm.build.build_model(scene).
model.spheres is the SphereModel (pass it to fsm.Simulation); model.skin.evaluate(positions) gives
the deformed render surface.)")
      .def_readonly("name", &T::name, "the scene's name")
      .def_property_readonly(
          "spheres", [](T& t) -> SphereModel<Scalar>& { return t.spheres; },
          py::return_value_policy::reference_internal, "the SphereModel (by reference)")
      .def_readonly("parts", &T::parts, "the Parts, in scene order")
      .def_readonly("first_attachment_link", &T::first_attachment_link,
                    "index of the first link joining two parts")
      .def_readonly("num_attachment_links", &T::num_attachment_links,
                    "how many links join parts (they follow first_attachment_link)")
      .def_property_readonly(
          "skin", [](T& t) -> S& { return t.skin; }, py::return_value_policy::reference_internal,
          "the Skin (by reference)")
      .def_readonly("report_json", &T::report_json, "the builder's report (JSON text)")
      .def("part", &T::part, py::arg("name"), py::return_value_policy::reference_internal,
           "The Part of that name; fsm.Error if there is none.")
      .def("validate", &T::validate,
           "Raises fsm.Error for anything inconsistent (parts, links, skin).")
      .def("__repr__", [](const T& t) {
        return "TissueModel('" + t.name + "', " + std::to_string(t.parts.size()) + " parts, " +
               std::to_string(t.spheres.num_nodes()) + " spheres)";
      });

  m.def("save_model", &save_model, py::arg("path"), py::arg("model"),
        py::call_guard<py::gil_scoped_release>(), "Writes a model file (docs/model_file.md).");
  m.def("load_model", &load_model, py::arg("path"), py::call_guard<py::gil_scoped_release>(),
        "Reads a model file; fsm.Error names the file and the reason for anything wrong.");
}

}  // namespace fsm::python
