#include "fsm/simulation.hpp"

namespace fsm {
template class Simulation<float>;
template class Simulation<double>;
}  // namespace fsm
