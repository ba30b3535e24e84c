// Builds a small block with the installed headers and library, steps it, and checks it moved.
#include <fsm/fsm.hpp>

#include <cstdio>

int main() {
  fsm::SphereModel<double> model;
  fsm::Material<double> tissue;
  tissue.density = 1050;
  tissue.youngs_modulus = 13150;
  tissue.viscosity = 10.26;
  const auto mesh = fsm::make_cube_lattice<double>({0, 0, 0}, {3, 3, 3}, 0.005);
  fsm::add_tetrahedral_part(model, mesh, model.add_region("block", tissue), 0.0025);
  for (fsm::Index i = 0; i < model.num_nodes(); ++i)
    if (model.rest_positions()(i, 2) < 1e-9) model.set_fixed(i);
  fsm::Simulation<double> sim(model);
  for (int s = 0; s < 100; ++s)
    if (!sim.step(1e-3).advanced()) return 1;
  const double sag = sim.model().positions().col(2).minCoeff() - 0.0;
  std::printf("fsm %s downstream: %d spheres, %d links, sag under gravity %.3g mm\n", fsm::version,
              model.num_nodes(), model.num_links(),
              -1e3 * (sim.model().positions() - sim.model().rest_positions()).col(2).minCoeff());
  (void)sag;
  return (sim.model().positions() - sim.model().rest_positions()).col(2).minCoeff() < 0 ? 0 : 2;
}
