// fsm::build from an installed tree (the GPL builder component): fill a closed mesh with
// tetrahedra and check the filling is a valid mesh inside the surface, filling most of it (a
// coarse filling cuts corners: docs/builder.md).
#include <fsm/builder/fillings.hpp>
#include <fsm/builder/mesh_io.hpp>

#include <cmath>
#include <cstdio>

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  const auto surface = fsm::build::read_mesh(argv[1], 0.01);  // cm
  const auto fill =
      fsm::build::fill_tetrahedral(surface, *fsm::build::isotropic_metric(0.003), "", "downstream");
  fill.mesh.validate("downstream");
  const double ratio = fill.mesh.volume() / surface.volume();
  std::printf("fsm::build downstream: %d spheres, %d tetrahedra, %.1f %% of the volume\n",
              int(fill.mesh.vertices.rows()), int(fill.mesh.tetrahedra.rows()), 100 * ratio);
  return ratio > 0.7 && ratio < 1.01 ? 0 : 3;
}
