#pragma once

/// @file material.hpp
/// @brief Material (density, Young's modulus, viscosity, optional bilinear modulus) and the rules
/// that turn a material into link constants.

#include <cmath>
#include <limits>
#include <string>

#include "fsm/error.hpp"
#include "fsm/voigt_link.hpp"

namespace fsm {

/// @brief A homogeneous, isotropic Voigt material (docs/physics.md section 10.1, eq. 2):
/// \f$\sigma = E\varepsilon + \eta\dot\varepsilon\f$, optionally bilinear in \f$E\f$.
///
/// The link law (the paper's) uses E, eta and the bilinear pair; its network has Poisson's ratio
/// 1/4 whatever `poisson_ratio` says. The continuum law (docs/physics.md section 11) uses E and
/// `poisson_ratio` as the small-strain constants of its neo-Hookean energy, eta as a Voigt
/// viscosity on the strain rate (retardation time eta / E), and the bilinear pair as a stiffening
/// of its deviatoric energy.
template <typename Scalar>
struct Material {
  Scalar density{1000};      ///< \f$\rho\f$ (kg/m^3), > 0.
  Scalar youngs_modulus{0};  ///< \f$E\f$ (Pa), > 0: the small-strain modulus.
  Scalar viscosity{0};       ///< \f$\eta\f$ (Pa s), >= 0.
  /// \f$E_L\f$ (Pa): modulus beyond the switch strain; 0 means linear (no switch).
  Scalar large_strain_modulus{0};
  /// \f$\varepsilon_s\f$: |strain| where \f$E\f$ gives way to \f$E_L\f$; used when
  /// large_strain_modulus > 0.
  Scalar switch_strain{0};
  /// \f$\nu\f$, in (-1, 0.5): Poisson's ratio of the continuum law (soft tissue: 0.45-0.49).
  Scalar poisson_ratio{Scalar(0.45)};
  /// Strain \f$(l - l_0)/l_0\f$ past which the tissue tears (docs/physics.md section 12): a link
  /// stretched past it breaks, and in a continuum region so do the tetrahedra that share it.
  /// > 0; infinity (the default) = it never tears.
  Scalar tear_strain{std::numeric_limits<Scalar>::infinity()};

  /// @brief True when the material has a modulus switch.
  [[nodiscard]] bool is_bilinear() const noexcept { return large_strain_modulus > Scalar(0); }

  /// @brief Retardation time \f$\tau = \eta / E\f$ (s) of the Voigt element.
  [[nodiscard]] Scalar retardation_time() const noexcept { return viscosity / youngs_modulus; }
  /// @brief Shear modulus \f$\mu = E / (2(1+\nu))\f$ (Pa) of the continuum law.
  [[nodiscard]] Scalar shear_modulus() const noexcept {
    return youngs_modulus / (Scalar(2) * (Scalar(1) + poisson_ratio));
  }
  /// @brief Bulk modulus \f$K = E / (3(1-2\nu))\f$ (Pa) of the continuum law.
  [[nodiscard]] Scalar bulk_modulus() const noexcept {
    return youngs_modulus / (Scalar(3) * (Scalar(1) - Scalar(2) * poisson_ratio));
  }

  /// @brief Throws fsm::Error naming `what` (e.g. "region 'body'") if a value is out of range.
  void validate(const std::string& what) const {
    auto bad = [&](const char* field, Scalar value, const char* want) {
      throw Error("", what, std::string(field) + " = " + std::to_string(value) + " " + want);
    };
    if (!(std::isfinite(density) && density > 0))
      bad("density", density, "kg/m^3 must be positive");
    if (!(std::isfinite(youngs_modulus) && youngs_modulus > 0))
      bad("youngs_modulus", youngs_modulus, "Pa must be positive");
    if (!(std::isfinite(viscosity) && viscosity >= 0))
      bad("viscosity", viscosity, "Pa s must be non-negative");
    if (!(std::isfinite(large_strain_modulus) && large_strain_modulus >= 0))
      bad("large_strain_modulus", large_strain_modulus, "Pa must be non-negative (0 = linear)");
    if (is_bilinear() && !(std::isfinite(switch_strain) && switch_strain > 0))
      bad("switch_strain", switch_strain, "must be positive for a bilinear material");
    if (!(poisson_ratio > Scalar(-1) && poisson_ratio < Scalar(0.5)))
      bad("poisson_ratio", poisson_ratio, "must be in (-1, 0.5)");
    if (!(tear_strain > Scalar(0)))  // NaN fails too; infinity = never tears
      bad("tear_strain", tear_strain, "must be positive (infinity = never tears)");
  }
};

/// @brief Link constants for an edge of a tetrahedral mesh: Van Gelder's rule.
///
/// \f[ k_s = \frac{E \sum_{T \ni e} V_T}{l_e^2}, \qquad k_d = \frac{\eta \sum_{T \ni e}
/// V_T}{l_e^2},
///     \qquad k_L = \frac{E_L \sum_{T \ni e} V_T}{l_e^2}, \f]
/// the three-dimensional form of A. Van Gelder, "Approximate simulation of elastic membranes by
/// triangulated spring meshes", Journal of Graphics Tools 3(2):21-42, 1998 (stiffness as element
/// size over edge length squared, summed over the elements that share the edge).
///
/// What it guarantees (derivation in docs/physics.md): for any tetrahedral mesh, the network's
/// small-strain stiffness tensor has the isotropic part of a material with Young's modulus E and
/// Poisson's ratio 1/4, so the bulk modulus \f$2E/3\f$ is exact on every mesh and E is exact on an
/// isotropic aggregate of elements. A regular lattice is anisotropic: the Freudenthal cube lattice
/// of make_cube_lattice() has \f$30E/29\f$ along its axes (tests/test_material.cpp measures it).
///
/// @param material the part's material.
/// @param incident_volume \f$\sum_{T\ni e} V_T\f$ (m^3), > 0.
/// @param rest_length \f$l_e\f$ (m), > 0.
template <typename Scalar>
[[nodiscard]] VoigtLink<Scalar> tetrahedral_link(const Material<Scalar>& material,
                                                 Scalar incident_volume, Scalar rest_length) {
  const Scalar g = incident_volume / (rest_length * rest_length);
  if (material.is_bilinear()) {
    return VoigtLink<Scalar>::bilinear(rest_length, material.youngs_modulus * g,
                                       material.viscosity * g, material.large_strain_modulus * g,
                                       material.switch_strain);
  }
  return VoigtLink<Scalar>::linear(rest_length, material.youngs_modulus * g,
                                   material.viscosity * g);
}

/// @brief Link constants for a rod of cross-section A and length l (a sphere chain along an axis):
/// \f$k_s = E A / l\f$, \f$k_d = \eta A / l\f$ (the axial stiffness of a bar).
template <typename Scalar>
[[nodiscard]] VoigtLink<Scalar> rod_link(const Material<Scalar>& material, Scalar area,
                                         Scalar rest_length) {
  const Scalar g = area / rest_length;
  if (material.is_bilinear()) {
    return VoigtLink<Scalar>::bilinear(rest_length, material.youngs_modulus * g,
                                       material.viscosity * g, material.large_strain_modulus * g,
                                       material.switch_strain);
  }
  return VoigtLink<Scalar>::linear(rest_length, material.youngs_modulus * g,
                                   material.viscosity * g);
}

}  // namespace fsm
