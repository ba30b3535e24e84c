#include "fsm/sphere_model.hpp"

namespace fsm {
template class SphereModel<float>;
template class SphereModel<double>;
}  // namespace fsm
