#include "fsm/volume_term.hpp"

namespace fsm {
template class VolumeTerm<float>;
template class VolumeTerm<double>;
}  // namespace fsm
