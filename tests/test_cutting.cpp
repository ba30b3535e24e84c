// Cutting and tearing (fsm/cutting.hpp, Simulation::cut, tearing inside Simulation::step).

#include "fsm/cutting.hpp"

#include "fsm/cut_surface.hpp"

#include <gtest/gtest.h>

#include <array>
#include <map>
#include <set>

#include "common.hpp"

namespace fsm {
namespace {

using V3 = Vector3<double>;

TEST(SegmentCrossesTriangle, CrossingMissingParallelAndTouching) {
  const V3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  EXPECT_TRUE(segment_crosses_triangle<double>(V3(0.2, 0.2, -1), V3(0.2, 0.2, 1), a, b, c));
  EXPECT_TRUE(segment_crosses_triangle<double>(V3(0.2, 0.2, 1), V3(0.2, 0.2, -1), a, b, c));
  EXPECT_FALSE(segment_crosses_triangle<double>(V3(0.8, 0.8, -1), V3(0.8, 0.8, 1), a, b, c));
  EXPECT_FALSE(segment_crosses_triangle<double>(V3(0.2, 0.2, 0.1), V3(0.2, 0.2, 1), a, b, c));
  EXPECT_FALSE(segment_crosses_triangle<double>(V3(-1, 0.2, 0), V3(1, 0.2, 0), a, b, c));
  EXPECT_TRUE(segment_crosses_triangle<double>(V3(0.2, 0.2, 0), V3(0.2, 0.2, 1), a, b, c));
  EXPECT_FALSE(segment_crosses_triangle<double>(V3(0.2, 0.2, -1), V3(0.2, 0.2, 1), a, a, c));
}

TEST(Blade, ZeroLengthOrNonFiniteIsAnError) {
  Blade<double> blade;
  blade.start_b = V3(1, 0, 0);
  blade.end_a = V3(0, 0, -1);
  blade.end_b = V3(1, 0, -1);
  EXPECT_NO_THROW(blade.validate());
  Blade<double> zero = blade;
  zero.end_b = zero.end_a;
  EXPECT_THROW(zero.validate(), Error);
  Blade<double> nan = blade;
  nan.start_a.x() = std::nan("");
  try {
    nan.validate();
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("blade"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("not finite"), std::string::npos);
  }
  // The simulation reports it and changes nothing.
  Simulation<double> sim(test::block<double>({2, 2, 2}, 0.005));
  const TopologyChange c = sim.cut(zero);
  EXPECT_TRUE(c.rejected);
  EXPECT_FALSE(c.any());
  EXPECT_EQ(sim.model().num_broken_links(), 0);
}

// The block (6 x 2 x 2 cells of 5 mm) held at x = 0, a blade swept down through x = 17.5 mm.
SphereModel<double> held_bar(ForceLaw law) {
  SphereModel<double> model = test::block<double>({6, 2, 2}, 0.005);
  model.set_region_law(0, law);
  test::fix_below(model, 0);
  return model;
}

Blade<double> through_bar(double x) {
  Blade<double> blade;
  blade.start_a = V3(x, -0.002, 0.013);
  blade.start_b = V3(x, 0.012, 0.013);
  blade.end_a = V3(x, -0.002, -0.003);
  blade.end_b = V3(x, 0.012, -0.003);
  return blade;
}

class CutBar : public ::testing::TestWithParam<ForceLaw> {};

TEST_P(CutBar, SeparatesIntoTwoPiecesThatFallApartAndKeepTheirMass) {
  Simulation<double>::Options o;
  o.forces.gravity = V3(0, 0, -9.81);
  Simulation<double> sim(held_bar(GetParam()), o);
  const double mass = sim.model().total_mass();
  const Blade<double> blade = through_bar(0.0175);
  const TopologyChange c = sim.cut(blade);
  ASSERT_FALSE(c.rejected);
  EXPECT_GT(c.links_cut, 0);
  EXPECT_GT(c.tetrahedra_cut, 0);
  EXPECT_EQ(c.pieces, 2);
  EXPECT_EQ(c.loose_pieces, 1);
  EXPECT_EQ(sim.model().total_mass(), mass);
  EXPECT_EQ(Index(sim.topology().broken_links().size()), c.links_cut);
  // No intact link, and no edge of an intact tetrahedron, crosses the blade's path.
  const auto& m = sim.model();
  const auto x = m.positions();
  for (Index l = 0; l < m.num_links(); ++l) {
    if (!m.link_intact()[l]) continue;
    EXPECT_FALSE(segment_crosses_blade<double>(x.row(m.links()(l, 0)).transpose(),
                                               x.row(m.links()(l, 1)).transpose(), blade))
        << "link " << l;
  }
  for (Index t = 0; t < m.num_tetrahedra(); ++t) {
    if (!m.tetrahedron_intact()[t]) continue;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b)
        EXPECT_FALSE(segment_crosses_blade<double>(x.row(m.tetrahedra()(t, a)).transpose(),
                                                   x.row(m.tetrahedra()(t, b)).transpose(), blade));
  }
  // The free piece (every node beyond the cut) falls freely; the held one hangs on.
  std::vector<Index> loose, held;
  for (Index i = 0; i < m.num_nodes(); ++i)
    (m.rest_positions()(i, 0) > 0.0175 ? loose : held).push_back(i);
  auto com_z = [&](const std::vector<Index>& nodes) {
    double mz = 0, mm = 0;
    for (Index i : nodes) {
      mz += m.masses()[i] * m.positions()(i, 2);
      mm += m.masses()[i];
    }
    return mz / mm;
  };
  const double z_loose = com_z(loose), z_held = com_z(held);
  const int steps = 200;
  const double h = 1e-3;
  for (int s = 0; s < steps; ++s) ASSERT_TRUE(sim.step(h).advanced()) << s;
  // Implicit Euler under constant gravity: the free centre of mass drops g h^2 n (n + 1) / 2.
  const double drop = 9.81 * h * h * steps * (steps + 1) / 2;
  EXPECT_TRUE(test::near(z_loose - com_z(loose), drop, 1e-6)) << "the free piece falls freely";
  EXPECT_LT(z_held - com_z(held), 0.05 * drop) << "the held piece sags a little, no more";
  EXPECT_EQ(sim.model().total_mass(), mass);
}

TEST_P(CutBar, ForcesStayBalancedAfterTheCut) {
  Simulation<double>::Options o;
  o.forces.gravity.setZero();
  SphereModel<double> model = held_bar(GetParam());
  for (Index i = 0; i < model.num_nodes(); ++i) model.set_fixed(i, false);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  Simulation<double> sim(model, o);
  for (Index i = 0; i < sim.model().num_nodes(); ++i)
    for (int c = 0; c < 3; ++c) {
      sim.model().positions()(i, c) += 4e-4 * u(rng);
      sim.model().velocities()(i, c) = 0.01 * u(rng);
    }
  ASSERT_TRUE(sim.cut(through_bar(0.0125)).any());
  Positions<double> f(sim.model().num_nodes(), 3);
  sim.forces().evaluate(sim.model(), sim.model().positions(), sim.model().velocities(), f);
  V3 net = V3::Zero(), torque = V3::Zero();
  double scale = 0;
  for (Index i = 0; i < sim.model().num_nodes(); ++i) {
    net += f.row(i).transpose();
    torque += V3(sim.model().positions().row(i)).cross(V3(f.row(i)));
    scale += f.row(i).norm();
  }
  EXPECT_LT(net.norm(), 1e-9 * scale);
  EXPECT_LT(torque.norm(), 1e-9 * scale * 0.03);
  // Damping never adds energy: with no load the energy only falls through the steps.
  double e = sim.energy().total();
  for (int s = 0; s < 50; ++s) {
    ASSERT_TRUE(sim.step(1e-3).advanced());
    const double now = sim.energy().total();
    EXPECT_LE(now, e * (1 + 1e-9) + 1e-15) << s;
    e = now;
  }
}

INSTANTIATE_TEST_SUITE_P(BothLaws, CutBar, ::testing::Values(ForceLaw::links, ForceLaw::continuum),
                         [](const auto& p) { return std::string(to_string(p.param)); });

// A skin over the filling's own boundary: one render vertex per boundary sphere, bound to it
// through the first tetrahedron that has it.
Skin<double> boundary_skin(const SphereModel<double>& model) {
  std::map<std::array<Index, 3>, std::pair<int, std::array<Index, 3>>> faces;
  const auto tets = model.tetrahedra();
  static constexpr int face[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  for (Index t = 0; t < model.num_tetrahedra(); ++t)
    for (int k = 0; k < 4; ++k) {
      std::array<Index, 3> f{tets(t, face[k][0]), tets(t, face[k][1]), tets(t, face[k][2])};
      std::array<Index, 3> key = f;
      std::sort(key.begin(), key.end());
      auto& e = faces[key];
      ++e.first;
      e.second = f;
    }
  std::map<Index, Index> vertex;  // sphere -> render vertex
  std::vector<std::array<Index, 3>> out;
  for (const auto& [key, e] : faces) {
    if (e.first != 1) continue;
    std::array<Index, 3> f{};
    for (int k = 0; k < 3; ++k) {
      auto it = vertex.emplace(e.second[std::size_t(k)], Index(vertex.size())).first;
      f[std::size_t(k)] = it->second;
    }
    out.push_back(f);
  }
  Skin<double> skin;
  const Index nv = Index(vertex.size());
  skin.rest.vertices.resize(nv, 3);
  skin.rest.faces.resize(Index(out.size()), 3);
  for (std::size_t f = 0; f < out.size(); ++f)
    for (int k = 0; k < 3; ++k) skin.rest.faces(Index(f), k) = out[f][std::size_t(k)];
  skin.kind.setZero(nv);
  skin.nodes.resize(nv, 4);
  skin.weights.setZero(nv, 4);
  skin.offsets.setZero(nv, 3);
  for (const auto& [sphere, v] : vertex) {
    skin.rest.vertices.row(v) = model.rest_positions().row(sphere);
    for (Index t = 0; t < model.num_tetrahedra(); ++t) {
      int at = -1;
      for (int k = 0; k < 4; ++k)
        if (tets(t, k) == sphere) at = k;
      if (at < 0) continue;
      skin.nodes.row(v) = tets.row(t);
      skin.weights(v, at) = 1;
      break;
    }
  }
  skin.surfaces.push_back({"block", 0, nv, 0, Index(out.size())});
  skin.validate(model.num_nodes());
  return skin;
}

// The render surface of a cut: no visible face spans the cut, the wound's walls appear.
TEST(CutSurface, NoFaceSpansTheCutAndTheWoundHasWalls) {
  Simulation<double>::Options o;
  o.forces.gravity = V3(0, 0, -9.81);
  Simulation<double> sim(held_bar(ForceLaw::continuum), o);
  const Skin<double> skin = boundary_skin(sim.model());
  CutSurface<double> surface(sim.model(), skin);
  EXPECT_EQ(surface.num_hidden(), 0);
  EXPECT_EQ(surface.num_walls(), 0);
  auto ws = skin.make_workspace();
  Positions<double> render(skin.num_vertices(), 3);
  skin.evaluate(sim.model().positions(), ws, render);
  const Blade<double> blade = through_bar(0.0175);
  ASSERT_EQ(sim.cut(blade).pieces, 2);
  surface.add_cut(blade, render);
  surface.update(sim.model());
  EXPECT_GT(surface.num_hidden(), 0);
  ASSERT_GT(surface.num_walls(), 0);
  // Walls: faces of intact tetrahedra across from removed ones, one per such face.
  const auto& m = sim.model();
  Index expected_walls = 0;
  std::map<std::array<Index, 3>, std::vector<Index>> at_face;
  for (Index t = 0; t < m.num_tetrahedra(); ++t)
    for (int k = 0; k < 4; ++k) {
      std::array<Index, 3> f{m.tetrahedra()(t, (k + 1) % 4), m.tetrahedra()(t, (k + 2) % 4),
                             m.tetrahedra()(t, (k + 3) % 4)};
      std::sort(f.begin(), f.end());
      at_face[f].push_back(t);
    }
  for (const auto& [f, ts] : at_face)
    if (ts.size() == 2 && m.tetrahedron_intact()[ts[0]] != m.tetrahedron_intact()[ts[1]])
      ++expected_walls;
  EXPECT_EQ(surface.num_walls(), expected_walls);
  for (Index w = 0; w < surface.num_walls(); ++w) {
    std::array<Index, 3> f{surface.wall_faces()(w, 0), surface.wall_faces()(w, 1),
                           surface.wall_faces()(w, 2)};
    std::sort(f.begin(), f.end());
    ASSERT_EQ(at_face[f].size(), 2u);
  }
  // Let the free piece fall away; every visible face still lies within one piece, and none is
  // stretched across the gap.
  for (int s = 0; s < 150; ++s) ASSERT_TRUE(sim.step(1e-3).advanced());
  skin.evaluate(sim.model().positions(), ws, render);
  TopologyChange pieces;
  sim.topology().count_pieces(sim.model(), sim.forces().force_links(), pieces);
  ASSERT_EQ(pieces.pieces, 2);
  Index visible = 0;
  for (Index f = 0; f < skin.rest.num_faces(); ++f) {
    if (surface.hidden(f)) continue;
    ++visible;
    std::set<Index> piece;
    for (int k = 0; k < 3; ++k) {
      const Index v = skin.rest.faces(f, k);
      for (int j = 0; j < 4; ++j)
        if (skin.weights(v, j) != 0) piece.insert(sim.topology().piece(skin.nodes(v, j)));
    }
    EXPECT_EQ(piece.size(), 1u) << "face " << f;
    for (int k = 0; k < 3; ++k)
      EXPECT_LT(
          (render.row(skin.rest.faces(f, k)) - render.row(skin.rest.faces(f, (k + 1) % 3))).norm(),
          0.0075);
  }
  EXPECT_GT(visible, skin.rest.num_faces() / 2);
  // Walls follow the same rule: each within one piece.
  for (Index w = 0; w < surface.num_walls(); ++w) {
    std::set<Index> piece;
    for (int k = 0; k < 3; ++k) piece.insert(sim.topology().piece(surface.wall_faces()(w, k)));
    EXPECT_EQ(piece.size(), 1u);
  }
  sim.model().restore_topology();
  surface.restore(sim.model());
  EXPECT_EQ(surface.num_hidden(), 0);
  EXPECT_EQ(surface.num_walls(), 0);
}

// add_cut on its own hides exactly the skin faces with an edge the blade crossed.
TEST(CutSurface, AddCutHidesExactlyTheFacesTheBladeCrossed) {
  const SphereModel<double> model = held_bar(ForceLaw::links);
  const Skin<double> skin = boundary_skin(model);
  CutSurface<double> surface(model, skin);
  Blade<double> blade = through_bar(0.0175);
  blade.end_a.z() = blade.end_b.z() = 0.006;  // a partial cut, from the top
  const Index hidden = surface.add_cut(blade, skin.rest.vertices);
  Index expected = 0;
  for (Index f = 0; f < skin.rest.num_faces(); ++f) {
    bool crossed = false;
    for (int k = 0; k < 3; ++k)
      crossed = crossed ||
                segment_crosses_blade<double>(
                    skin.rest.vertices.row(skin.rest.faces(f, k)).transpose(),
                    skin.rest.vertices.row(skin.rest.faces(f, (k + 1) % 3)).transpose(), blade);
    EXPECT_EQ(surface.hidden(f), crossed) << f;
    expected += crossed;
    if (surface.hidden(f)) {  // written degenerate
      EXPECT_EQ(surface.skin_faces()(f, 0), surface.skin_faces()(f, 1));
      EXPECT_EQ(surface.skin_faces()(f, 1), surface.skin_faces()(f, 2));
    } else {
      EXPECT_EQ(surface.skin_faces().row(f), skin.rest.faces.row(f));
    }
  }
  EXPECT_GT(expected, 0);
  EXPECT_EQ(hidden, expected);
}

TEST(Cut, APartialCutLeavesOnePieceAndABladeThatMissesCutsNothing) {
  Simulation<double> sim(held_bar(ForceLaw::links));
  Blade<double> half = through_bar(0.0175);
  half.end_a.z() = half.end_b.z() = 0.006;  // down to mid-height only
  const TopologyChange c = sim.cut(half);
  EXPECT_GT(c.links_cut, 0);
  EXPECT_EQ(c.pieces, 1);
  EXPECT_EQ(c.loose_pieces, 0);
  Blade<double> away = through_bar(0.2);
  const TopologyChange none = sim.cut(away);
  EXPECT_FALSE(none.any());
  EXPECT_TRUE(sim.topology().broken_links().empty());
}

// A tear threshold breaks exactly the links strained past it.
TEST(Tear, BreaksExactlyTheLinksPastTheThreshold) {
  SphereModel<double> model = test::block<double>({3, 3, 3}, 0.005);
  TopologyEditor<double> editor(model);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.02, 0.3);
  for (Index l = 0; l < model.num_links(); ++l) editor.tear_strains()[l] = u(rng);
  editor.refresh_tearing(model);
  ASSERT_TRUE(editor.tears());
  // A non-uniform stretch: strains from 0 to about 0.25 across directions and places.
  for (Index i = 0; i < model.num_nodes(); ++i) {
    const V3 p = model.rest_positions().row(i).transpose();
    model.positions().row(i) = V3(p.x() * (1 + 15 * p.y()), p.y() * 1.1, p.z()).transpose();
  }
  std::set<Index> expect;
  for (Index l = 0; l < model.num_links(); ++l) {
    const double len =
        (model.positions().row(model.links()(l, 1)) - model.positions().row(model.links()(l, 0)))
            .norm();
    if (len > model.rest_lengths()[l] * (1 + editor.tear_strains()[l])) expect.insert(l);
  }
  ASSERT_GT(expect.size(), 10u);
  ASSERT_LT(expect.size(), std::size_t(model.num_links()) - 10);
  const TopologyChange c = editor.tear(model);
  EXPECT_EQ(std::size_t(c.links_torn), expect.size());
  const std::set<Index> got(editor.broken_links().begin(), editor.broken_links().end());
  EXPECT_EQ(got, expect);
  for (Index l = 0; l < model.num_links(); ++l)
    EXPECT_EQ(model.link_intact()[l], expect.count(l) ? 0 : 1);
  // Every tetrahedron with a torn edge is removed, and only those.
  for (Index t = 0; t < model.num_tetrahedra(); ++t) {
    bool has_torn = false;
    for (Index l : expect) {
      const auto [b, e] = editor.tetrahedra_at_link(l);
      has_torn = has_torn || std::find(b, e, t) != e;
    }
    EXPECT_EQ(model.tetrahedron_intact()[t], has_torn ? 0 : 1) << t;
  }
  // Nothing more tears at the same state.
  EXPECT_FALSE(editor.tear(model).any());
}

TEST(Tear, NegativeOrNaNThresholdIsAnError) {
  Material<double> m = test::tissue<double>();
  m.tear_strain = -0.1;
  EXPECT_THROW(m.validate("region 'x'"), Error);
  m.tear_strain = std::nan("");
  EXPECT_THROW(m.validate("region 'x'"), Error);
  SphereModel<double> model = test::block<double>({1, 1, 1}, 0.005);
  TopologyEditor<double> editor(model);
  editor.tear_strains()[0] = std::nan("");
  EXPECT_THROW(editor.refresh_tearing(model), Error);
}

// Pulled apart by a load, a bar tears inside the step where its material says, the step reports
// it, the free end falls away, and no state is NaN.
TEST(Tear, ABarPulledByALoadTearsInsideTheStep) {
  for (const ForceLaw law : {ForceLaw::links, ForceLaw::continuum}) {
    Material<double> mat = test::tissue<double>(3000.0, 5.0);
    mat.tear_strain = 0.3;
    SphereModel<double> model = test::block<double>({6, 1, 1}, 0.005, mat);
    model.set_region_law(0, law);
    test::fix_below(model, 0);
    Simulation<double>::Options o;
    o.forces.gravity.setZero();
    o.forces.drag = 5;
    Simulation<double> sim(model, o);
    Index torn = 0, steps_to_tear = -1;
    for (Index i = 0; i < sim.model().num_nodes(); ++i)
      if (sim.model().rest_positions()(i, 0) > 0.0299) sim.external_forces()(i, 0) = 0.02;
    for (int s = 0; s < 3000 && torn == 0; ++s) {
      const StepReport<double> r = sim.step(1e-3);
      ASSERT_TRUE(r.advanced()) << to_string(law) << " step " << s;
      torn += r.torn.links_torn;
      if (r.torn.links_torn > 0) {
        steps_to_tear = s;
        EXPECT_GE(r.torn.pieces, 1);
        EXPECT_EQ(Index(sim.topology().broken_links().size()), r.torn.links_torn);
      }
    }
    EXPECT_GT(torn, 0) << to_string(law) << ": the load should tear the bar";
    EXPECT_GE(steps_to_tear, 0);
    // Every link still intact is within its tear strain.
    const auto& m = sim.model();
    for (Index l = 0; l < m.num_links(); ++l) {
      if (!m.link_intact()[l]) continue;
      EXPECT_LE((m.positions().row(m.links()(l, 1)) - m.positions().row(m.links()(l, 0))).norm(),
                1.3 * m.rest_lengths()[l] * (1 + 1e-12));
    }
    for (int s = 0; s < 100; ++s) ASSERT_TRUE(sim.step(1e-3).advanced());
    EXPECT_TRUE(sim.model().positions().allFinite());
  }
}

// The step's incremental updates (the force model by what broke, the pieces by a search from
// the wound) agree with a rebuild from scratch after every one of a series of random cuts.
TEST(Topology, IncrementalUpdatesMatchARebuild) {
  for (const ForceLaw law : {ForceLaw::links, ForceLaw::continuum}) {
    SphereModel<double> model = test::block<double>({5, 3, 3}, 0.005);
    model.set_region_law(0, law);
    test::fix_below(model, 0);
    Simulation<double> sim(model);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(0, 1);
    Index cuts = 0;
    for (int k = 0; k < 25; ++k) {
      // A blade across the block at a random place and angle, part or all the way through.
      const double x = 0.003 + 0.02 * u(rng), y0 = -0.002 + 0.006 * u(rng), depth = 0.016 * u(rng);
      const double tilt = 0.004 * (u(rng) - 0.5);
      Blade<double> blade;
      blade.start_a = V3(x, y0, 0.017);
      blade.start_b = V3(x + tilt, y0 + 0.02, 0.017);
      blade.end_a = V3(x + tilt, y0, 0.017 - depth - 0.002);
      blade.end_b = V3(x, y0 + 0.02, 0.017 - depth - 0.002);
      const TopologyChange c = sim.cut(blade);
      if (!c.any()) continue;
      ++cuts;
      TopologyEditor<double> fresh(sim.model());
      ForceModel<double> rebuilt(sim.model(), sim.forces().options());
      TopologyChange full;
      fresh.count_pieces(sim.model(), rebuilt.force_links(), full);
      EXPECT_EQ(c.pieces, full.pieces) << to_string(law) << " cut " << k;
      EXPECT_EQ(c.loose_pieces, full.loose_pieces) << to_string(law) << " cut " << k;
      // The same partition of the nodes.
      std::map<Index, Index> to_full;
      for (Index i = 0; i < sim.model().num_nodes(); ++i) {
        const auto [it, inserted] = to_full.emplace(sim.topology().piece(i), fresh.piece(i));
        EXPECT_EQ(it->second, fresh.piece(i)) << "node " << i;
      }
      EXPECT_EQ(Index(to_full.size()), full.pieces);
      EXPECT_EQ(sim.forces().force_links(), rebuilt.force_links());
      Positions<double> f(sim.model().num_nodes(), 3), g(sim.model().num_nodes(), 3);
      sim.model().velocities().setRandom();
      sim.model().velocities() *= 0.01;
      sim.forces().evaluate(sim.model(), sim.model().positions(), sim.model().velocities(), f);
      rebuilt.evaluate(sim.model(), sim.model().positions(), sim.model().velocities(), g);
      EXPECT_TRUE(test::matrices_near(f, g, 1e-12)) << to_string(law) << " cut " << k;
      for (int s = 0; s < 5; ++s) ASSERT_TRUE(sim.step(1e-3).advanced());
    }
    EXPECT_GT(cuts, 10) << to_string(law);
  }
}

TEST(Topology, RestoreMakesTheModelWholeAgain) {
  Simulation<double> sim(held_bar(ForceLaw::continuum));
  ASSERT_TRUE(sim.cut(through_bar(0.0175)).any());
  EXPECT_GT(sim.model().num_broken_links(), 0);
  EXPECT_GT(sim.model().num_removed_tetrahedra(), 0);
  sim.model().restore_topology();
  sim.refresh();
  EXPECT_EQ(sim.model().num_broken_links(), 0);
  EXPECT_EQ(sim.model().num_removed_tetrahedra(), 0);
  for (int s = 0; s < 50; ++s) ASSERT_TRUE(sim.step(1e-3).advanced());
}

}  // namespace
}  // namespace fsm
