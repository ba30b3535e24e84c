// Blade, TopologyChange and CutSurface (fsm/cutting.hpp, fsm/cut_surface.hpp); Simulation.cut is
// bound with the simulation.

#include "common.hpp"

namespace fsm::python {

void define_cutting(py::module_& m) {
  using B = Blade<Scalar>;
  py::class_<B>(m, "Blade", R"(A cutting edge swept over one step.

Blade(start_a, start_b, end_a, end_b): the edge runs from start_a to start_b before the step and
from end_a to end_b after it (m); it cuts what crosses the surface between the two. fsm.Error for a
non-finite point or an edge of zero length.)")
      .def(py::init([](const Vector3<Scalar>& sa, const Vector3<Scalar>& sb,
                       const Vector3<Scalar>& ea, const Vector3<Scalar>& eb) {
             B b{sa, sb, ea, eb};
             b.validate();
             return b;
           }),
           py::arg("start_a"), py::arg("start_b"), py::arg("end_a"), py::arg("end_b"))
      .def_readonly("start_a", &B::start_a, "one end of the edge before the step (m)")
      .def_readonly("start_b", &B::start_b, "the other end before the step (m)")
      .def_readonly("end_a", &B::end_a, "start_a's end after the step (m)")
      .def_readonly("end_b", &B::end_b, "start_b's end after the step (m)")
      .def(
          "crosses",
          [](const B& b, const Vector3<Scalar>& p, const Vector3<Scalar>& q) {
            return segment_crosses_blade(p, q, b);
          },
          py::arg("p"), py::arg("q"), "True if the segment p-q crosses the swept surface.");

  py::class_<TopologyChange>(m, "TopologyChange", "What a cut or a tear changed.")
      .def_readonly("links_cut", &TopologyChange::links_cut, "links the blade crossed")
      .def_readonly("tetrahedra_cut", &TopologyChange::tetrahedra_cut,
                    "tetrahedra with an edge the blade crossed")
      .def_readonly("links_torn", &TopologyChange::links_torn,
                    "links strained past their tear strain")
      .def_readonly("tetrahedra_torn", &TopologyChange::tetrahedra_torn,
                    "tetrahedra that shared a torn link")
      .def_readonly("pieces", &TopologyChange::pieces,
                    "pieces the model is in after the change (0 when nothing changed)")
      .def_readonly("loose_pieces", &TopologyChange::loose_pieces,
                    "pieces with no fixed sphere (they fall)")
      .def_readonly("rejected", &TopologyChange::rejected, "the blade was invalid: nothing changed")
      .def_property_readonly("any", &TopologyChange::any, "True if anything broke")
      .def("__repr__", [](const TopologyChange& c) {
        return "TopologyChange(links_cut=" + std::to_string(c.links_cut) +
               ", tetrahedra_cut=" + std::to_string(c.tetrahedra_cut) +
               ", links_torn=" + std::to_string(c.links_torn) +
               ", tetrahedra_torn=" + std::to_string(c.tetrahedra_torn) +
               ", pieces=" + std::to_string(c.pieces) + ")";
      });

  using CS = CutSurface<Scalar>;
  py::class_<CS>(m, "CutSurface", R"(The render surface of a cut or torn model.

CutSurface(model, skin): skin_faces is the skin's face array with the faces that span a wound made
degenerate; walls (sphere indices) are the exposed faces of intact tetrahedra. Call add_cut(blade,
vertices) with the skin's render vertices at each cut and update(model) after each change.)")
      .def(py::init<const SphereModel<Scalar>&, const Skin<Scalar>&>(), py::arg("model"),
           py::arg("skin"))
      .def(
          "add_cut",
          [](CS& s, const B& blade, const Positions<Scalar>& vertices) {
            return s.add_cut(blade, vertices);
          },
          py::arg("blade"), py::arg("vertices"),
          "Hides the skin faces the blade crossed; returns how many.")
      .def("update", &CS::update, py::arg("model"),
           "Follows the model's broken links and removed tetrahedra.")
      .def("restore", &CS::restore, py::arg("model"), "Shows every face again, no walls.")
      .def_property_readonly(
          "skin_faces", [](const CS& s) { return FaceArray(s.skin_faces()); },
          "|F| x 3 (a copy): the skin's faces, hidden ones degenerate")
      .def_property_readonly(
          "walls", [](const CS& s) { return FaceArray(s.wall_faces().topRows(s.num_walls())); },
          "|W| x 3 sphere indices (a copy): the wound's walls")
      .def_property_readonly("num_hidden", &CS::num_hidden, "skin faces hidden so far")
      .def("hidden", &CS::hidden, py::arg("face"), "True if skin face `face` is hidden.");
}

}  // namespace fsm::python
