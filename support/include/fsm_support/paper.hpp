#pragma once

/// @file fsm_support/paper.hpp
/// @brief The reference paper's tissue (docs/physics.md section 10): the porcine uterus of its
/// indentation experiment. One place for its constants, for the programs around the library.

#include "fsm/material.hpp"

namespace fsm::support::paper {

inline constexpr double density = 1050;                ///< kg/m^3 (soft tissue; not in the paper)
inline constexpr double youngs_modulus = 13150;        ///< Pa: the small-deformation modulus
inline constexpr double large_strain_modulus = 68380;  ///< Pa: the large-deformation modulus
inline constexpr double viscosity = 10.26;             ///< Pa s
/// The strain where the bilinear law switches. The paper does not give it; 10 % is ours.
inline constexpr double switch_strain = 0.10;

/// @brief The paper's tissue with the linear law (E and eta only).
template <typename Scalar = double>
Material<Scalar> linear_tissue() {
  Material<Scalar> m;
  m.density = Scalar(density);
  m.youngs_modulus = Scalar(youngs_modulus);
  m.viscosity = Scalar(viscosity);
  return m;
}

/// @brief The paper's bilinear tissue: 13.15 / 68.38 kPa, 10.26 Pa s, switching at 10 %.
template <typename Scalar = double>
Material<Scalar> bilinear_tissue() {
  Material<Scalar> m = linear_tissue<Scalar>();
  m.large_strain_modulus = Scalar(large_strain_modulus);
  m.switch_strain = Scalar(switch_strain);
  return m;
}

}  // namespace fsm::support::paper
