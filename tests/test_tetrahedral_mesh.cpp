// Tetrahedral parts and lattices: counts, orientation, exact mass, link constants, bad meshes.

#include <set>

#include "common.hpp"

namespace fsm::test {
namespace {

TEST(Lattice, FreudenthalBoxCountsAndOrientation) {
  const Eigen::Vector3i cells(3, 4, 5);
  const auto mesh = make_cube_lattice<double>(Vector3<double>(1, 2, 3), cells, 0.01);
  EXPECT_EQ(mesh.vertices.rows(), 4 * 5 * 6);
  EXPECT_EQ(mesh.tetrahedra.rows(), 6 * 3 * 4 * 5);
  for (Index t = 0; t < mesh.tetrahedra.rows(); ++t)
    EXPECT_TRUE(near(mesh.signed_volume(t), 1e-6 / 6, 1e-9)) << "tet " << t;
  EXPECT_TRUE(near(mesh.volume(), 60e-6, 1e-12));
  EXPECT_TRUE(near(mesh.vertices.col(0).minCoeff(), 1.0, 1e-15));
  EXPECT_NO_THROW(mesh.validate("lattice"));
}

TEST(Lattice, ShapeFilterKeepsCellsInsideAndDropsUnusedVertices) {
  const double r = 0.02;
  const auto mesh =
      make_cube_lattice<double>(Vector3<double>(-r, -r, -r), {8, 8, 8}, 0.005,
                                [&](const Vector3<double>& c) { return c.norm() < r; });
  EXPECT_NO_THROW(mesh.validate("ball"));  // validate() rejects unused vertices
  // The kept cubes approximate the ball's volume.
  EXPECT_TRUE(near(mesh.volume(), 4.0 / 3.0 * M_PI * r * r * r, 0.15));
}

TEST(TetrahedralPart, OneNodePerVertexOneLinkPerEdgeExactMass) {
  SphereModel<double> model;
  const Material<double> mat = tissue<double>();
  const Index r = model.add_region("block", mat);
  const Eigen::Vector3i c(2, 3, 4);
  const auto mesh = make_cube_lattice<double>(Vector3<double>::Zero(), c, 0.01);
  const PartRange range = add_tetrahedral_part(model, mesh, r, 0.004);
  EXPECT_EQ(range.num_nodes, mesh.vertices.rows());
  // Distinct edges of the Freudenthal lattice: 7 per cube plus those on the max faces.
  std::set<std::pair<Index, Index>> edges;
  for (Index t = 0; t < mesh.tetrahedra.rows(); ++t)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b)
        edges.insert(std::minmax(mesh.tetrahedra(t, a), mesh.tetrahedra(t, b)));
  EXPECT_EQ(range.num_links, Index(edges.size()));
  EXPECT_TRUE(near(model.total_mass(), mat.density * mesh.volume(), 1e-12));
  // An interior axis edge is shared by 6 tetrahedra of volume h^3/6: k = E h^3 / h^2 = E h.
  double kmax = 0;
  for (Index l = 0; l < model.num_links(); ++l)
    if (std::abs(model.rest_lengths()[l] - 0.01) < 1e-12)
      kmax = std::max(kmax, model.stiffness()[l]);
  EXPECT_TRUE(near(kmax, mat.youngs_modulus * 0.01, 1e-12));
  EXPECT_NO_THROW(model.validate());
}

TEST(TetrahedralPart, BadMeshesAreRejectedAndTheModelKept) {
  SphereModel<double> model;
  const Index r = model.add_region("body", tissue<double>());
  TetrahedralMesh<double> mesh;
  mesh.vertices.resize(4, 3);
  mesh.vertices << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  mesh.vertices *= 0.01;
  mesh.tetrahedra.resize(1, 4);
  mesh.tetrahedra << 0, 1, 2, 3;
  EXPECT_NO_THROW(add_tetrahedral_part(model, mesh, r, 0.003));
  const Index nodes = model.num_nodes();

  auto expect_error = [&](TetrahedralMesh<double> bad, double radius, const std::string& what) {
    try {
      add_tetrahedral_part(model, bad, r, radius);
      ADD_FAILURE() << "no error for " << what;
    } catch (const Error& e) {
      EXPECT_EQ(e.part(), "region 'body'");
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
    EXPECT_EQ(model.num_nodes(), nodes);
  };
  auto flat = mesh;
  flat.vertices.row(3) << 0.005, 0.005, 0;
  expect_error(flat, 0.003, "degenerate");
  auto oob = mesh;
  oob.tetrahedra(0, 2) = 9;
  expect_error(oob, 0.003, "out of range");
  auto rep = mesh;
  rep.tetrahedra(0, 3) = 0;
  expect_error(rep, 0.003, "repeats");
  auto nan = mesh;
  nan.vertices(1, 1) = std::nan("");
  expect_error(nan, 0.003, "not finite");
  expect_error(mesh, -0.001, "radius");
  TetrahedralMesh<double> empty;
  expect_error(empty, 0.003, "empty");
  auto twice = mesh;
  twice.tetrahedra.conservativeResize(2, 4);
  twice.tetrahedra.row(1) << 3, 1, 2, 0;
  expect_error(twice, 0.003, "repeats tetrahedron 0");
}

}  // namespace
}  // namespace fsm::test
