#pragma once

// Shared pieces of the _fsm extension: the scalar the bindings use, numpy views without copies,
// and shape checks with useful messages.

#include <pybind11/eigen.h>
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
template <typename T>
py::array_t<T> view(T* data, py::ssize_t rows, py::ssize_t cols, py::handle owner) {
  if (cols == 0) return py::array_t<T>({rows}, {py::ssize_t(sizeof(T))}, data, owner);
  return py::array_t<T>({rows, cols}, {py::ssize_t(sizeof(T)) * cols, py::ssize_t(sizeof(T))}, data,
                        owner);
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

// The C++ solver skips compute() and project() silently when the model's size differs from the
// one it was sized for (they are noexcept); Python should hear about it, so the bound class
// remembers the size.
class BoundContactSolver : public collision::ContactSolver<Scalar> {
 public:
  BoundContactSolver(const SphereModel<Scalar>& model,
                     const collision::ContactOptions<Scalar>& options)
      : collision::ContactSolver<Scalar>(model, options), m_nodes(model.num_nodes()) {}
  void refresh(const SphereModel<Scalar>& model) {
    collision::ContactSolver<Scalar>::refresh(model);
    m_nodes = model.num_nodes();
  }
  [[nodiscard]] Index num_nodes() const noexcept { return m_nodes; }
  void check(const SphereModel<Scalar>& model, const char* what) const {
    if (model.num_nodes() != m_nodes)
      throw Error("", what,
                  "has " + std::to_string(model.num_nodes()) +
                      " spheres but the solver was sized for " + std::to_string(m_nodes) +
                      " (call refresh(model) after growing the model)");
  }

 private:
  Index m_nodes{0};
};

void define_material(py::module_& m);
void define_sphere_model(py::module_& m);
void define_tetrahedral_mesh(py::module_& m);
void define_integrators(py::module_& m);
void define_simulation(py::module_& m);
void define_tissue_model(py::module_& m);
void define_collision(py::module_& m);
void define_haptics(py::module_& m);
void define_volume_term(py::module_& m);

}  // namespace fsm::python
