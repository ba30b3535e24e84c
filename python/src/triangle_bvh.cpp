// collision/triangle_bvh.hpp: the AABB tree over a moving triangle surface, ray and point queries.

#include <limits>

#include "common.hpp"
#include "fsm/collision/triangle_bvh.hpp"

namespace fsm::python {

namespace {
namespace fc = fsm::collision;
using Bvh = fc::TriangleBvh<Scalar>;
using RayHit = fc::RayHit<Scalar>;
}  // namespace

void define_triangle_bvh(py::module_& m) {
  // ---- triangle BVH ----------------------------------------------------------------------------
  py::class_<RayHit>(m, "RayHit", R"(A ray hit: face index, distance (m) and barycentrics.

u and v weight the face's vertices 1 and 2 (vertex 0 gets 1 - u - v).)")
      .def_readonly("face", &RayHit::face, "the face index (-1 from intersect_ray_triangle)")
      .def_readonly("distance", &RayHit::distance, "m from the ray origin")
      .def_readonly("u", &RayHit::u, "barycentric weight of the face's vertex 1")
      .def_readonly("v", &RayHit::v, "barycentric weight of the face's vertex 2")
      .def("__repr__", [](const RayHit& h) {
        return "RayHit(face=" + std::to_string(h.face) +
               ", distance=" + std::to_string(h.distance) + ", u=" + std::to_string(h.u) +
               ", v=" + std::to_string(h.v) + ")";
      });

  const auto faces_of = [](const py::array_t<Index, py::array::c_style | py::array::forcecast>& f) {
    if (f.ndim() != 2 || f.shape(1) != 3)
      throw Error("", "faces", "has shape " + shape_string(f) + ", wanted (n, 3)");
    FaceArray out(f.shape(0), 3);
    std::copy(f.data(), f.data() + f.size(), out.data());
    return out;
  };

  py::class_<Bvh>(m, "TriangleBvh", R"(An AABB tree over a moving triangle surface (picking,
surface contact).

TriangleBvh(vertices, faces): vertices (|V|, 3) in m, faces (|F|, 3) vertex indices. Build once,
refit(vertices) each frame as the surface deforms (same |V|), then ray_cast() or faces_near().
Raises fsm.Error naming a bad vertex or face. The tree keeps its own copy of the triangles.)")
      .def(
          py::init([faces_of](
                       const Array& vertices,
                       const py::array_t<Index, py::array::c_style | py::array::forcecast>& faces) {
            const Positions<Scalar> v = rows3(vertices, "vertices");
            const FaceArray f = faces_of(faces);
            auto bvh = std::make_unique<Bvh>();
            {
              py::gil_scoped_release release;
              bvh->build(v, f);
            }
            return bvh;
          }),
          py::arg("vertices"), py::arg("faces"))
      .def(
          "build",
          [faces_of](Bvh& bvh, const Array& vertices,
                     const py::array_t<Index, py::array::c_style | py::array::forcecast>& faces) {
            const Positions<Scalar> v = rows3(vertices, "vertices");
            const FaceArray f = faces_of(faces);
            py::gil_scoped_release release;
            bvh.build(v, f);
          },
          py::arg("vertices"), py::arg("faces"),
          "Rebuilds the tree for a new surface (fsm.Error for a bad one; the tree is then "
          "unchanged).")
      .def(
          "refit",
          [](Bvh& bvh, const Array& vertices) {
            if (vertices.ndim() != 2 || vertices.shape(0) != bvh.num_vertices() ||
                vertices.shape(1) != 3)
              throw Error("", "vertices",
                          "has shape " + shape_string(vertices) + ", wanted (" +
                              std::to_string(bvh.num_vertices()) + ", 3) as at build()");
            const Eigen::Map<const Positions<Scalar>> v(vertices.data(), vertices.shape(0), 3);
            require_finite(v, "vertices");
            bool ok = false;
            {
              py::gil_scoped_release release;
              ok = bvh.refit(v);
            }
            if (!ok) throw Error("", "vertices", "the tree could not be refitted to them");
          },
          py::arg("vertices"),
          "Moves the surface to new vertex positions (|V|, 3) in O(|F|); the topology is kept.")
      .def(
          "ray_cast",
          [](const Bvh& bvh, const Vector3<Scalar>& origin, const Vector3<Scalar>& direction,
             Scalar max_distance) -> std::optional<RayHit> {
            require_finite(origin, "origin");
            require_direction(direction, "direction");
            require_non_negative(max_distance, "max_distance", true);
            return bvh.ray_cast(origin, direction, max_distance);
          },
          py::arg("origin"), py::arg("direction"),
          py::arg("max_distance") = std::numeric_limits<Scalar>::infinity(),
          R"(The nearest hit of the ray origin + t direction (any non-zero length), or None.

Returns a RayHit with the Euclidean distance (m) from origin, 0 <= distance <= max_distance.
Faces are two-sided and the test is watertight; ties go to the smallest face index.)")
      .def(
          "faces_near",
          [](const Bvh& bvh, const Vector3<Scalar>& centre, Scalar radius) {
            require_finite(centre, "centre");
            require_non_negative(radius, "radius");
            const Index n = bvh.faces_near(centre, radius, nullptr, 0);
            py::array_t<Index> out(n);
            if (n > 0) bvh.faces_near(centre, radius, out.mutable_data(), n);
            return out;
          },
          py::arg("centre"), py::arg("radius"),
          R"(Indices (int32 array, tree order) of the faces whose triangle comes within radius (m) of
centre (m).)")
      .def_property_readonly("num_faces", &Bvh::num_faces, "|F|")
      .def_property_readonly("num_vertices", &Bvh::num_vertices, "|V| that refit() expects")
      .def_property_readonly("depth", &Bvh::depth, "depth of the deepest leaf")
      .def("__repr__", [](const Bvh& b) {
        return "TriangleBvh(" + std::to_string(b.num_faces()) + " faces, depth " +
               std::to_string(b.depth()) + ")";
      });

  m.def(
      "intersect_ray_triangle",
      [](const Vector3<Scalar>& origin, const Vector3<Scalar>& direction, const Vector3<Scalar>& a,
         const Vector3<Scalar>& b, const Vector3<Scalar>& c,
         Scalar max_t) -> std::optional<RayHit> {
        require_finite(origin, "origin");
        require_direction(direction, "direction");
        require_finite(a, "a");
        require_finite(b, "b");
        require_finite(c, "c");
        require_non_negative(max_t, "max_t", true);
        return fc::intersect_ray_triangle(origin, direction, a, b, c, max_t);
      },
      py::arg("origin"), py::arg("direction"), py::arg("a"), py::arg("b"), py::arg("c"),
      py::arg("max_t") = std::numeric_limits<Scalar>::infinity(),
      R"(Watertight ray-triangle test (Woop, Benthin and Wald 2013): a RayHit whose distance is the
ray parameter t (hit = origin + t direction) and face -1, or None.)");
  m.def("closest_point_on_triangle", &fc::closest_point_on_triangle<Scalar>, py::arg("p"),
        py::arg("a"), py::arg("b"), py::arg("c"),
        "The point (m) of the closed triangle (a, b, c) nearest to p (Ericson 2005, 5.1.5).");
}

}  // namespace fsm::python
