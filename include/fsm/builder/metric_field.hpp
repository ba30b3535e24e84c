#pragma once

/// @file build/metric_field.hpp
/// @brief Metric-tensor fields that drive the tetrahedral filling (docs/physics.md section 10.3).

#include <Eigen/Core>
#include <memory>
#include <string>

namespace fsm::build {

/// @brief A field of 3x3 symmetric positive definite metric tensors
/// \f$\mathbf{M}(\mathbf{x}) = \mathbf{P}\,\mathrm{diag}(h_1^{-2}, h_2^{-2},
/// h_3^{-2})\,\mathbf{P}^T\f$ (1/m^2): an element edge \f$\mathbf{e}\f$ has metric length
/// \f$\sqrt{\mathbf{e}^T\mathbf{M} \mathbf{e}}\f$, and a well-sized element has metric edges of
/// length about 1, i.e. physical size \f$h_i\f$ along the eigenvector \f$\mathbf{p}_i\f$.
///
/// How the filling honours each kind (docs/builder.md):
/// - constant fields (isotropic or anisotropic) exactly: the part is mapped by
///   \f$\mathbf{M}^{1/2}\f$ into a space where the metric is the identity, filled there with
///   unit-size elements, and mapped back;
/// - spatially varying fields in size only: Delaunay refinement follows the smallest size
///   \f$\min_i h_i(\mathbf{x})\f$ at each point, isotropically.
class MetricField {
 public:
  virtual ~MetricField() = default;
  /// @brief \f$\mathbf{M}(\mathbf{x})\f$ (1/m^2) at a point (m).
  [[nodiscard]] virtual Eigen::Matrix3d metric(const Eigen::Vector3d& x) const = 0;
  /// @brief True when \f$\mathbf{M}\f$ does not depend on the point.
  [[nodiscard]] virtual bool is_constant() const noexcept = 0;
  /// @brief A short description for reports ("isotropic h = 5 mm", ...).
  [[nodiscard]] virtual std::string describe() const = 0;
  /// @brief The smallest element size (m) the metric asks for at a point:
  /// \f$\lambda_{max}^{-1/2}\f$.
  [[nodiscard]] double size(const Eigen::Vector3d& x) const;
};

/// @brief \f$\mathbf{M} = \mathbf{I}/h^2\f$: elements of size h everywhere.
std::shared_ptr<const MetricField> isotropic_metric(double size);

/// @brief A constant anisotropic metric: sizes `sizes[i]` (m) along the orthonormalised `axes`
/// columns. fsm::Error for non-positive sizes or degenerate axes.
std::shared_ptr<const MetricField> anisotropic_metric(const Eigen::Vector3d& sizes,
                                                      const Eigen::Matrix3d& axes);

/// @brief An isotropic size graded with distance r from `centre`, h_min within `plateau_radius` r_0
/// of it: \f$h(r) = h_{min} + (h_{max} - h_{min})\,\mathrm{clamp}((r - r_0) / d, 0, 1)\f$ (m).
/// fsm::Error for a size or distance that is not positive and finite, a plateau radius that is
/// negative or not finite, or a centre that is not finite.
std::shared_ptr<const MetricField> graded_metric(double size_min, double size_max,
                                                 const Eigen::Vector3d& centre, double distance,
                                                 double plateau_radius = 0);

/// @brief Element quality in a metric (docs/physics.md section 10.3, the scale-invariant form of
/// eq. 14): \f$Q(K) = \alpha\,(\sum_i \mathbf{e}_i^T\mathbf{M}\mathbf{e}_i)^{3/2} /
/// (|K|\sqrt{\det\mathbf{M}})\f$ over the six edges, \f$\alpha = 1/(72\sqrt3)\f$ so a regular
/// tetrahedron in the metric has \f$Q = 1\f$; \f$Q \ge 1\f$, infinite for a flat element.
double tetrahedron_quality(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                           const Eigen::Vector3d& c, const Eigen::Vector3d& d,
                           const Eigen::Matrix3d& metric);

/// @brief The smallest of a tetrahedron's six dihedral angles (degrees).
double min_dihedral_angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                          const Eigen::Vector3d& c, const Eigen::Vector3d& d);

}  // namespace fsm::build
