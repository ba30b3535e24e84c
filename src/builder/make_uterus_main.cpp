/// @file make_uterus_main.cpp
/// @brief `make-uterus OUTPUT_DIR`: writes the default data set (one OBJ per part in cm and the
/// scene `uterus.json`) and prints what it wrote.

#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>

#include "fsm/builder/uterus_generator.hpp"
#include "fsm_support/cli.hpp"

int main(int argc, char** argv) {
  CLI::App app(
      "Writes the procedural uterus (body, fibroid, ovaries, ovarian ligaments, fallopian "
      "tubes) as OBJ surfaces in cm and the scene OUTPUT_DIR/uterus.json.",
      "make-uterus");
  fsm::support::add_version_flag(app);
  std::string directory;
  app.add_option("OUTPUT_DIR", directory, "where to write the meshes and the scene")->required();
  if (const int status = fsm::support::parse_command_line(app, argc, argv); status >= 0)
    return status;
  try {
    const fsm::build::UterusShape shape;
    const std::string scene = fsm::build::write_uterus_scene(directory, shape);
    // write_uterus_scene() generates the same (deterministic) meshes; generate them again to
    // report them.
    const fsm::build::UterusMeshes meshes = fsm::build::generate_uterus(shape);
    std::printf("%-16s %8s %8s %14s\n", "part", "vertices", "faces", "volume (cm^3)");
    for (std::size_t i = 0; i < meshes.names.size(); ++i) {
      const auto& mesh = meshes.meshes[i];
      const std::string file =
          (std::filesystem::path(directory) / (meshes.names[i] + ".obj")).string();
      std::printf("%-16s %8d %8d %14.3f  %s\n", meshes.names[i].c_str(), int(mesh.num_vertices()),
                  int(mesh.num_faces()), mesh.volume() * 1e6, file.c_str());
    }
    std::printf("scene: %s\n", scene.c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make-uterus: %s\n", e.what());
    return 1;
  }
  return 0;
}
