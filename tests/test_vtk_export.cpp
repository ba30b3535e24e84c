// VtkSeriesWriter: the files and the index it writes, and what it refuses. That ParaView's readers
// accept the content is checked by reading it back with meshio (examples/demo/check_export.py).

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "fsm/fsm.hpp"
#include "scratch_dir.hpp"

namespace fsm {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

std::size_t count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

class VtkExport : public ::testing::Test {
 protected:
  void SetUp() override {
    dir = test::scratch_dir("fsm_vtk_export");
    Material<double> tissue;
    tissue.density = 1050;
    tissue.youngs_modulus = 13150;
    tissue.viscosity = 10.26;
    add_tetrahedral_part(model, make_cube_lattice<double>({0, 0, 0}, {2, 2, 1}, 0.005),
                         model.add_region("block", tissue), 0.0025);
  }
  void TearDown() override { fs::remove_all(dir); }
  fs::path dir;
  SphereModel<double> model;
};

TEST_F(VtkExport, WritesOnePiecePerStateAndAnIndex) {
  VtkSeriesWriter writer(dir.string(), model);
  const Positions<double> zero = Positions<double>::Zero(model.num_nodes(), 3);
  writer.write(0.001, model.positions(), zero, zero);
  writer.write(0.002, model.positions(), zero, zero);
  EXPECT_EQ(writer.states(), 2u);
  const std::string piece = slurp(dir / "fsm_spheres_000001.vtu");
  EXPECT_NE(piece.find("NumberOfPoints=\"" + std::to_string(model.num_nodes()) + "\""),
            std::string::npos);
  EXPECT_NE(piece.find("NumberOfCells=\"" +
                       std::to_string(model.num_links() + model.num_tetrahedra()) + "\""),
            std::string::npos);
  for (const char* name : {"radius", "velocity", "force", "fixed", "region", "kind"})
    EXPECT_NE(piece.find(std::string("Name=\"") + name + "\""), std::string::npos) << name;
  EXPECT_FALSE(fs::exists(dir / "fsm_surface_000000.vtu"));  // no skin given
  const std::string index = slurp(writer.series_path());
  EXPECT_EQ(count(index, "<DataSet "), 2u);
  EXPECT_NE(index.find("timestep=\"0.002\" part=\"0\" file=\"fsm_spheres_000001.vtu\""),
            std::string::npos);
}

TEST_F(VtkExport, RefusesWhatItCannotWrite) {
  VtkSeriesWriter writer(dir.string(), model);
  const Positions<double> zero = Positions<double>::Zero(model.num_nodes(), 3);
  const Positions<double> short_array = Positions<double>::Zero(3, 3);
  EXPECT_THROW(writer.write(0.0, short_array, zero, zero), Error);
  writer.write(0.0, model.positions(), zero, zero);
  EXPECT_THROW(writer.write(0.0, model.positions(), zero, zero), Error);  // time not after
  EXPECT_THROW(writer.write(std::nan(""), model.positions(), zero, zero), Error);
  EXPECT_EQ(writer.states(), 1u);
  EXPECT_THROW(VtkSeriesWriter(dir.string(), model, nullptr, "a/b"), Error);
  std::ofstream(dir / "a_file") << "x";
  try {
    VtkSeriesWriter w((dir / "a_file" / "sub").string(), model);
    ADD_FAILURE() << "a folder under a file was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("a_file"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace fsm
