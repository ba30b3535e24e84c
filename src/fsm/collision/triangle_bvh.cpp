#include "fsm/collision/triangle_bvh.hpp"

namespace fsm::collision {
template class TriangleBvh<float>;
template class TriangleBvh<double>;
}  // namespace fsm::collision
