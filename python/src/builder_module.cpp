// The _fsm_build extension: the model builder (GPL-3.0-or-later, it links CGAL). Kept apart from
// _fsm so the runtime module stays BSD-licensed; import it as fsm.build.

#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "common.hpp"
#include "fsm/builder/builder.hpp"
#include "fsm/builder/uterus_generator.hpp"

PYBIND11_MODULE(_fsm_build, m) {
  namespace py = pybind11;
  using namespace fsm;
  m.doc() = R"(libfsm's model builder (GPL-3.0-or-later; import fsm.build instead).)";
  py::module_::import("fsm._fsm");  // TissueModel and fsm.Error live there
  m.def(
      "build_model",
      [](const std::string& scene_path) {
        build::BuildReport report;
        TissueModel<double> model;
        {
          py::gil_scoped_release release;
          model = build::build_model(scene_path, &report);
        }
        return py::make_tuple(std::move(model), report.json(), report.table());
      },
      py::arg("scene"),
      R"(Builds a scene file into (TissueModel, report_json, report_table). fsm.Error names the file,
part and reason for bad input.)");
  m.def(
      "write_uterus_scene",
      [](const std::string& directory) {
        py::gil_scoped_release release;
        return build::write_uterus_scene(directory);
      },
      py::arg("directory"),
      "Generates the procedural uterus (meshes and scene) into a folder; returns the scene path.");
  m.def(
      "read_mesh",
      [](const std::string& path, double scale, const std::vector<std::string>& nodes) {
        const TriangleMesh<double> mesh = build::read_mesh(path, scale, nodes);
        return py::make_tuple(mesh.vertices, mesh.faces);
      },
      py::arg("path"), py::arg("scale") = 1.0, py::arg("nodes") = std::vector<std::string>{},
      "Reads OBJ/OFF/STL/PLY/glTF (.gltf, .glb; `nodes`: the glTF nodes to take, each with its "
      "subtree and transforms, default all); returns (vertices |V| x 3 in m after scale, faces "
      "|F| x 3).");
  m.def(
      "inspect_mesh",
      [](const Positions<double>& vertices, const FaceArray& faces) {
        const build::MeshReport r = build::inspect_mesh(TriangleMesh<double>{vertices, faces});
        py::dict d;
        d["vertices"] = r.vertices;
        d["faces"] = r.faces;
        d["components"] = r.components;
        d["boundary_edges"] = r.boundary_edges;
        d["non_manifold_edges"] = r.non_manifold_edges;
        d["non_manifold_vertices"] = r.non_manifold_vertices;
        d["degenerate_faces"] = r.degenerate_faces;
        d["self_intersections"] = r.self_intersections;
        d["outward_oriented"] = r.outward_oriented;
        d["volume"] = r.volume;
        d["area"] = r.area;
        d["defects"] = r.defects();
        d["bounds_a_volume"] = r.bounds_a_volume();
        return d;
      },
      py::arg("vertices"), py::arg("faces"), "The defect report of a triangle mesh, as a dict.");
}
