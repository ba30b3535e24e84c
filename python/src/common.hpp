#pragma once

// Shared pieces of the _fsm extension: the scalar the bindings use, numpy views without copies,
// and shape checks with useful messages.

#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>

#include "fsm/fsm.hpp"

namespace fsm::python {

namespace py = pybind11;

/// The bindings use double throughout (researchers' scripts; float stays a C++ option).
using Scalar = double;

/// A numpy array over memory owned by `owner` (no copy). The array keeps `owner` alive.
/// Views are invalidated when the owner's arrays grow (adding nodes or links), like iterators.
/// A `read_only` view refuses writes (numpy raises ValueError): structure the C++ side indexes
/// with (links, regions, flags) is changed through checked setters only.
template <typename T>
py::array_t<T> view(T* data, py::ssize_t rows, py::ssize_t cols, py::handle owner,
                    bool read_only = false) {
  py::array_t<T> a =
      cols == 0
          ? py::array_t<T>({rows}, {py::ssize_t(sizeof(T))}, data, owner)
          : py::array_t<T>({rows, cols}, {py::ssize_t(sizeof(T)) * cols, py::ssize_t(sizeof(T))},
                           data, owner);
  if (read_only) a.attr("setflags")(py::arg("write") = false);
  return a;
}

/// Raises fsm.Error naming `what` unless `x` is a finite number >= 0 (infinity allowed when
/// `allow_infinity`).
inline void require_non_negative(Scalar x, const char* what, bool allow_infinity = false) {
  if (!(x >= 0) || (!allow_infinity && !std::isfinite(x)))
    throw Error(
        "", what,
        "is " + std::to_string(x) + "; it must be " +
            (allow_infinity ? "non-negative (infinity allowed)" : "finite and non-negative"));
}

/// Raises fsm.Error naming `what` unless `d` is a finite, non-zero direction.
inline void require_direction(const Vector3<Scalar>& d, const char* what) {
  if (!d.allFinite() || !(d.squaredNorm() > 0))
    throw Error("", what, "must be a finite, non-zero direction");
}

/// Raises fsm.Error naming `what` unless every entry of `a` is finite.
template <typename Derived>
void require_finite(const Eigen::DenseBase<Derived>& a, const char* what) {
  if (!a.allFinite()) throw Error("", what, "is not finite (NaN or infinite entries)");
}

/// Copies a (rows x 3) numpy array into an Eigen map after checking its shape; fsm::Error names
/// the argument, the shape given and the shape wanted.
template <typename Map>
void assign_rows3(Map&& dst,
                  const py::array_t<Scalar, py::array::c_style | py::array::forcecast>& src,
                  const char* what) {
  const auto rows = py::ssize_t(dst.rows());
  if (src.ndim() != 2 || src.shape(0) != rows || src.shape(1) != 3) {
    std::string got = "(";
    for (py::ssize_t d = 0; d < src.ndim(); ++d)
      got += (d ? ", " : "") + std::to_string(src.shape(d));
    got += src.ndim() == 1 ? ",)" : ")";
    throw Error("", what, "has shape " + got + ", wanted (" + std::to_string(rows) + ", 3)");
  }
  std::copy(src.data(), src.data() + rows * 3, dst.data());
}

/// The array type the bindings take for float input: converted to C-contiguous float64.
using Array = py::array_t<Scalar, py::array::c_style | py::array::forcecast>;

/// "(2, 3)": a numpy array's shape as Python prints it.
inline std::string shape_string(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) s += (d ? ", " : "") + std::to_string(a.shape(d));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

/// A (rows x 3) array from numpy (copied); fsm::Error with the shape got and wanted.
inline Positions<Scalar> rows3(const Array& a, const char* what) {
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw Error("", what, "has shape " + shape_string(a) + ", wanted (n, 3)");
  Positions<Scalar> out(a.shape(0), 3);
  std::copy(a.data(), a.data() + a.size(), out.data());
  return out;
}

/// A length-3 vector from numpy; fsm::Error with the shape got and wanted.
inline Vector3<Scalar> vec3(const Array& a, const char* what) {
  if (a.size() != 3 || a.ndim() > 2)
    throw Error("", what, "has shape " + shape_string(a) + ", wanted (3,)");
  return Vector3<Scalar>(a.data()[0], a.data()[1], a.data()[2]);
}

// A read-write length-3 property that reads as a numpy view of the member (writing into it
// changes the object) and accepts any length-3 sequence.
template <typename C>
void vec3_property(py::class_<C>& c, const char* name, Vector3<Scalar> C::*member,
                   const char* doc) {
  c.def_property(
      name,
      [member](py::object self) {
        C& obj = self.cast<C&>();
        return view((obj.*member).data(), 3, 0, self);
      },
      [member, name](C& obj, const Array& v) {
        const Vector3<Scalar> x = vec3(v, name);
        if (!x.allFinite()) throw Error("", name, "is not finite");
        obj.*member = x;
      },
      doc);
}

/// A unit quaternion from (w, x, y, z); fsm::Error for a zero or non-finite one.
inline Eigen::Quaterniond to_quaternion(const Eigen::Vector4d& wxyz) {
  Eigen::Quaterniond q(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
  if (!(q.norm() > 0) || !q.coeffs().allFinite())
    throw Error("", "orientation", "needs a non-zero, finite quaternion (w, x, y, z)");
  return q.normalized();
}
/// (w, x, y, z) of a quaternion.
inline Eigen::Vector4d to_wxyz(const Eigen::Quaterniond& q) {
  return {q.w(), q.x(), q.y(), q.z()};
}

void define_material(py::module_& m);
void define_sphere_model(py::module_& m);
void define_tetrahedral_mesh(py::module_& m);
void define_integrators(py::module_& m);
void define_simulation(py::module_& m);
void define_tissue_model(py::module_& m);
void define_shapes(py::module_& m);
void define_contact(py::module_& m);
void define_triangle_bvh(py::module_& m);
void define_haptic_device(py::module_& m);
void define_scripted_device(py::module_& m);
void define_servo_loop(py::module_& m);
void define_volume_term(py::module_& m);
void define_cutting(py::module_& m);
void define_grasper(py::module_& m);

}  // namespace fsm::python
