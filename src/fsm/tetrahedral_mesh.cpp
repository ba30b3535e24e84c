#include "fsm/tetrahedral_mesh.hpp"

namespace fsm {
template struct TetrahedralMesh<float>;
template struct TetrahedralMesh<double>;
template PartRange add_tetrahedral_part(SphereModel<float>&, const TetrahedralMesh<float>&, Index,
                                        float);
template PartRange add_tetrahedral_part(SphereModel<double>&, const TetrahedralMesh<double>&, Index,
                                        double);
}  // namespace fsm
