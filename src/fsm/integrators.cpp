#include <string>

#include "fsm/heun_integrator.hpp"
#include "fsm/implicit_euler_integrator.hpp"
#include "fsm/improved_euler_integrator.hpp"
#include "fsm/symplectic_euler_integrator.hpp"

namespace fsm {

template class ImprovedEulerIntegrator<float>;
template class ImprovedEulerIntegrator<double>;
template class HeunIntegrator<float>;
template class HeunIntegrator<double>;
template class SymplecticEulerIntegrator<float>;
template class SymplecticEulerIntegrator<double>;
template class ImplicitEulerIntegrator<float>;
template class ImplicitEulerIntegrator<double>;

std::vector<std::string> integrator_names() {
  return {"improved_euler", "heun", "symplectic_euler", "implicit_euler"};
}

template <typename Scalar>
std::unique_ptr<Integrator<Scalar>> make_integrator(std::string_view name) {
  if (name == "improved_euler") return std::make_unique<ImprovedEulerIntegrator<Scalar>>();
  if (name == "heun") return std::make_unique<HeunIntegrator<Scalar>>();
  if (name == "symplectic_euler") return std::make_unique<SymplecticEulerIntegrator<Scalar>>();
  if (name == "implicit_euler") return std::make_unique<ImplicitEulerIntegrator<Scalar>>();
  std::string valid;
  for (const auto& n : integrator_names()) valid += (valid.empty() ? "" : ", ") + n;
  throw Error("", "integrator '" + std::string(name) + "'", "unknown; valid names: " + valid);
}

template std::unique_ptr<Integrator<float>> make_integrator<float>(std::string_view);
template std::unique_ptr<Integrator<double>> make_integrator<double>(std::string_view);

}  // namespace fsm
