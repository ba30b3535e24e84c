// Skin: render vertices bound barycentrically to tetrahedra or to sphere chains. At rest the skin
// reproduces its rest surface; barycentric vertices follow any affine motion exactly; chain
// vertices keep their distance from the axis and follow rigid motion that does not twist the chain.

#include <random>

#include "common.hpp"

namespace fsm::test {
namespace {

using V3 = Vector3<double>;

// A skin over a 2 x 2 x 2-cell lattice: random points inside, each in the tetrahedron found by
// brute force.
struct TetraSkin {
  TetrahedralMesh<double> mesh = make_cube_lattice<double>(V3::Zero(), {2, 2, 2}, 0.01);
  Skin<double> skin;
  explicit TetraSkin(int points) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(0.0005, 0.0195);
    skin.rest.vertices.resize(points, 3);
    skin.rest.faces.resize(1, 3);
    skin.rest.faces << 0, 1, 2;
    skin.kind.setConstant(points, std::uint8_t(SkinKind::barycentric));
    skin.nodes.resize(points, 4);
    skin.weights.resize(points, 4);
    skin.offsets.setZero(points, 3);
    skin.chain_nodes.resize(0, 3);
    skin.chain_rest_tangents.resize(0, 3);
    for (Index v = 0; v < points; ++v) {
      const V3 p(u(rng), u(rng), u(rng));
      skin.rest.vertices.row(v) = p.transpose();
      for (Index t = 0; t < mesh.tetrahedra.rows(); ++t) {
        Matrix3<double> T;
        const V3 a = mesh.vertices.row(mesh.tetrahedra(t, 0)).transpose();
        for (int k = 0; k < 3; ++k)
          T.col(k) = mesh.vertices.row(mesh.tetrahedra(t, k + 1)).transpose() - a;
        const V3 w = T.inverse() * (p - a);
        if (w.minCoeff() >= -1e-12 && w.sum() <= 1 + 1e-12) {
          skin.nodes.row(v) = mesh.tetrahedra.row(t);
          skin.weights.row(v) << 1 - w.sum(), w.x(), w.y(), w.z();
          break;
        }
      }
    }
    skin.surfaces.push_back({"lattice", 0, points, 0, 1});
  }
};

TEST(Skin, BarycentricReproducesRestAndFollowsAffineMotion) {
  TetraSkin s(200);
  ASSERT_NO_THROW(s.skin.validate(Index(s.mesh.vertices.rows())));
  auto ws = s.skin.make_workspace();
  Positions<double> out(200, 3);
  s.skin.evaluate(s.mesh.vertices, ws, out);
  EXPECT_LT((out - s.skin.rest.vertices).cwiseAbs().maxCoeff(), 1e-17);  // rounding of 2 cm
  // Any affine map of the spheres moves every vertex by the same map.
  Matrix3<double> A;
  A << 1.1, 0.2, -0.1, 0.05, 0.9, 0.3, -0.2, 0.1, 1.2;
  const V3 b(0.01, -0.02, 0.005);
  Positions<double> moved = (s.mesh.vertices * A.transpose()).rowwise() + b.transpose();
  s.skin.evaluate(moved, ws, out);
  const Positions<double> expected =
      (s.skin.rest.vertices * A.transpose()).rowwise() + b.transpose();
  EXPECT_TRUE(matrices_near(out, expected, 1e-13));
}

// A straight chain of 6 spheres along x, with vertices on rings around it.
struct ChainSkin {
  Positions<double> spheres;
  Skin<double> skin;
  ChainSkin() {
    const int n = 6;
    spheres.resize(n, 3);
    for (int i = 0; i < n; ++i) spheres.row(i) << 0.005 * i, 0, 0;
    skin.chain_nodes.resize(n, 3);
    skin.chain_rest_tangents.resize(n, 3);
    for (int i = 0; i < n; ++i) {
      skin.chain_nodes.row(i) << std::max(i - 1, 0), i, std::min(i + 1, n - 1);
      skin.chain_rest_tangents.row(i) << 1, 0, 0;
    }
    const int rings = 20, around = 8;
    const Index nv = rings * around;
    skin.rest.vertices.resize(nv, 3);
    skin.kind.setConstant(nv, std::uint8_t(SkinKind::chain));
    skin.nodes.setConstant(nv, 4, -1);
    skin.weights.setZero(nv, 4);
    skin.offsets.resize(nv, 3);
    for (int r = 0; r < rings; ++r)
      for (int k = 0; k < around; ++k) {
        const Index v = r * around + k;
        const double x = 0.025 * r / (rings - 1), phi = 2 * M_PI * k / around;
        const V3 off(0, 0.003 * std::cos(phi), 0.003 * std::sin(phi));
        skin.rest.vertices.row(v) = (V3(x, 0, 0) + off).transpose();
        const int a = std::min(int(x / 0.005), n - 2);
        const double s = x / 0.005 - a;
        skin.nodes(v, 0) = a;
        skin.nodes(v, 1) = a + 1;
        skin.weights(v, 0) = 1 - s;
        skin.weights(v, 1) = s;
        skin.offsets.row(v) = off.transpose();
      }
    skin.rest.faces.resize(1, 3);
    skin.rest.faces << 0, 1, 2;
    skin.surfaces.push_back({"tube", 0, nv, 0, 1});
  }
};

TEST(Skin, ChainReproducesRestAndFollowsTranslationAndBending) {
  ChainSkin c;
  ASSERT_NO_THROW(c.skin.validate(6));
  auto ws = c.skin.make_workspace();
  Positions<double> out(c.skin.num_vertices(), 3);
  c.skin.evaluate(c.spheres, ws, out);
  EXPECT_LT((out - c.skin.rest.vertices).cwiseAbs().maxCoeff(), 1e-17);
  // Translation: exact.
  const V3 t(0.1, -0.2, 0.3);
  c.skin.evaluate(Positions<double>(c.spheres.rowwise() + t.transpose()), ws, out);
  EXPECT_TRUE(
      matrices_near(out, Positions<double>(c.skin.rest.vertices.rowwise() + t.transpose()), 1e-14));
  // A rotation about z (perpendicular to the chain) is a rigid motion without twist: exact.
  const Matrix3<double> R = Eigen::AngleAxisd(0.7, V3::UnitZ()).toRotationMatrix();
  c.skin.evaluate(Positions<double>(c.spheres * R.transpose()), ws, out);
  EXPECT_TRUE(matrices_near(out, Positions<double>(c.skin.rest.vertices * R.transpose()), 1e-13));
  // Bending into an arc: every vertex keeps its distance from its axis point.
  Positions<double> arc(6, 3);
  for (int i = 0; i < 6; ++i) {
    const double phi = 0.25 * i;
    arc.row(i) << 0.02 * std::sin(phi), 0.02 * (1 - std::cos(phi)), 0;
  }
  c.skin.evaluate(arc, ws, out);
  for (Index v = 0; v < c.skin.num_vertices(); ++v) {
    const V3 axis = (c.skin.weights(v, 0) * arc.row(c.skin.nodes(v, 0)) +
                     c.skin.weights(v, 1) * arc.row(c.skin.nodes(v, 1)))
                        .transpose();
    EXPECT_NEAR((out.row(v).transpose() - axis).norm(), 0.003, 1e-12) << v;
  }
}

TEST(Skin, ValidateNamesTheBadVertex) {
  TetraSkin s(10);
  auto expect = [](const Skin<double>& skin, Index spheres, const std::string& what) {
    try {
      skin.validate(spheres);
      ADD_FAILURE() << "no error for " << what;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  Skin<double> bad = s.skin;
  bad.nodes(3, 2) = 999;
  expect(bad, Index(s.mesh.vertices.rows()), "skin vertex 3");
  bad = s.skin;
  bad.weights(4, 0) += 0.5;
  expect(bad, Index(s.mesh.vertices.rows()), "sum to 1");
  bad = s.skin;
  bad.kind[5] = 7;
  expect(bad, Index(s.mesh.vertices.rows()), "unknown binding kind");
  bad = s.skin;
  bad.offsets.conservativeResize(5, 3);
  expect(bad, Index(s.mesh.vertices.rows()), "per-vertex arrays");
}

TEST(TriangleMeshTest, VolumeAndNormalsOfATetrahedron) {
  TriangleMesh<double> m;
  m.vertices.resize(4, 3);
  m.vertices << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  m.faces.resize(4, 3);
  m.faces << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;  // outward
  EXPECT_NEAR(m.volume(), 1.0 / 6.0, 1e-15);
  Positions<double> n(4, 3);
  compute_vertex_normals<double>(m.vertices, m.faces, n);
  EXPECT_NEAR(n.row(0).norm(), 1.0, 1e-15);
  EXPECT_LT(n.row(0).sum(), 0);  // the corner at the origin points away from the others
  EXPECT_GT(n.row(3).z(), 0);
}

}  // namespace
}  // namespace fsm::test
