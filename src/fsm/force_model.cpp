#include "fsm/force_model.hpp"

namespace fsm {
template class ForceModel<float>;
template class ForceModel<double>;
}  // namespace fsm
