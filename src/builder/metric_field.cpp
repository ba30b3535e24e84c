// Metric fields and element quality measures (no CGAL here).

#include "fsm/builder/metric_field.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "fsm/error.hpp"

namespace fsm::build {

namespace {

std::string mm(double metres) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g mm", metres * 1e3);
  return buf;
}

class IsotropicMetric final : public MetricField {
 public:
  explicit IsotropicMetric(double h) : m_h(h) {}
  Eigen::Matrix3d metric(const Eigen::Vector3d&) const override {
    return Eigen::Matrix3d::Identity() / (m_h * m_h);
  }
  bool is_constant() const noexcept override { return true; }
  std::string describe() const override { return "isotropic h = " + mm(m_h); }

 private:
  double m_h;
};

class AnisotropicMetric final : public MetricField {
 public:
  AnisotropicMetric(const Eigen::Vector3d& sizes, const Eigen::Matrix3d& axes)
      : m_sizes(sizes),
        m_M(axes * sizes.cwiseInverse().cwiseAbs2().asDiagonal() * axes.transpose()) {}
  Eigen::Matrix3d metric(const Eigen::Vector3d&) const override { return m_M; }
  bool is_constant() const noexcept override { return true; }
  std::string describe() const override {
    return "anisotropic h = " + mm(m_sizes[0]) + ", " + mm(m_sizes[1]) + ", " + mm(m_sizes[2]);
  }

 private:
  Eigen::Vector3d m_sizes;
  Eigen::Matrix3d m_M;
};

class GradedMetric final : public MetricField {
 public:
  GradedMetric(double lo, double hi, const Eigen::Vector3d& c, double d, double r0)
      : m_lo(lo), m_hi(hi), m_c(c), m_d(d), m_r0(r0) {}
  Eigen::Matrix3d metric(const Eigen::Vector3d& x) const override {
    const double t = std::clamp(((x - m_c).norm() - m_r0) / m_d, 0.0, 1.0);
    const double h = m_lo + (m_hi - m_lo) * t;
    return Eigen::Matrix3d::Identity() / (h * h);
  }
  bool is_constant() const noexcept override { return false; }
  std::string describe() const override {
    return "graded h = " + mm(m_lo) + (m_r0 > 0 ? " within " + mm(m_r0) : std::string()) + " to " +
           mm(m_hi) + " over " + mm(m_d);
  }

 private:
  double m_lo, m_hi;
  Eigen::Vector3d m_c;
  double m_d, m_r0;
};

void require_size(double h, const char* what) {
  if (!(std::isfinite(h) && h > 0))
    throw Error("", "metric", std::string(what) + " must be positive and finite");
}

}  // namespace

double MetricField::size(const Eigen::Vector3d& x) const {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(metric(x), Eigen::EigenvaluesOnly);
  return 1.0 / std::sqrt(es.eigenvalues().maxCoeff());
}

std::shared_ptr<const MetricField> isotropic_metric(double size) {
  require_size(size, "size");
  return std::make_shared<IsotropicMetric>(size);
}

std::shared_ptr<const MetricField> anisotropic_metric(const Eigen::Vector3d& sizes,
                                                      const Eigen::Matrix3d& axes) {
  for (int i = 0; i < 3; ++i) require_size(sizes[i], "every size");
  if (!axes.allFinite() || std::abs(axes.determinant()) < 1e-9 * axes.colwise().norm().prod())
    throw Error("", "metric", "anisotropic axes are degenerate");
  // Orthonormalise the axes (Gram-Schmidt in the given order) and keep a right-handed frame.
  Eigen::Matrix3d q = Eigen::HouseholderQR<Eigen::Matrix3d>(axes).householderQ();
  for (int i = 0; i < 3; ++i)
    if (q.col(i).dot(axes.col(i)) < 0) q.col(i) = -q.col(i);
  return std::make_shared<AnisotropicMetric>(sizes, q);
}

std::shared_ptr<const MetricField> graded_metric(double size_min, double size_max,
                                                 const Eigen::Vector3d& centre, double distance,
                                                 double plateau_radius) {
  require_size(size_min, "size_min");
  require_size(size_max, "size_max");
  require_size(distance, "distance");
  if (!centre.allFinite()) throw Error("", "metric", "graded centre is not finite");
  if (!(std::isfinite(plateau_radius) && plateau_radius >= 0))
    throw Error("", "metric", "graded plateau_radius must be non-negative and finite");
  return std::make_shared<GradedMetric>(size_min, size_max, centre, distance, plateau_radius);
}

double tetrahedron_quality(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                           const Eigen::Vector3d& c, const Eigen::Vector3d& d,
                           const Eigen::Matrix3d& M) {
  const Eigen::Vector3d e[6] = {b - a, c - a, d - a, c - b, d - b, d - c};
  double sum = 0;
  for (const auto& v : e) sum += v.dot(M * v);
  const double volume = std::abs((b - a).dot((c - a).cross(d - a))) / 6.0;
  const double det = M.determinant();
  if (!(volume > 0) || !(det > 0)) return std::numeric_limits<double>::infinity();
  return std::pow(sum, 1.5) / (72.0 * std::sqrt(3.0) * volume * std::sqrt(det));
}

double min_dihedral_angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                          const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  const Eigen::Vector3d p[4] = {a, b, c, d};
  static constexpr int edge[6][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 3, 1, 2},
                                     {1, 2, 0, 3}, {1, 3, 0, 2}, {2, 3, 0, 1}};
  double smallest = 180.0;
  for (const auto& e : edge) {
    const Eigen::Vector3d u = (p[e[1]] - p[e[0]]).normalized();
    Eigen::Vector3d s = p[e[2]] - p[e[0]], t = p[e[3]] - p[e[0]];
    s -= s.dot(u) * u;
    t -= t.dot(u) * u;
    const double cosine = s.normalized().dot(t.normalized());
    smallest = std::min(smallest, std::acos(std::clamp(cosine, -1.0, 1.0)) * 180.0 / M_PI);
  }
  return smallest;
}

}  // namespace fsm::build
