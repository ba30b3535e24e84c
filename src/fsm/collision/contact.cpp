#include "fsm/collision/contact.hpp"

namespace fsm::collision {
template class ContactSolver<float>;
template class ContactSolver<double>;
}  // namespace fsm::collision
