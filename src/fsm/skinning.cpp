#include "fsm/skinning.hpp"

namespace fsm {
template struct Skin<float>;
template struct Skin<double>;
}  // namespace fsm
