/// @file make_uterus_main.cpp
/// @brief `make-uterus OUTPUT_DIR`: writes the default data set (one OBJ per part in cm and the
/// scene `uterus.json`) and prints what it wrote.

#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>

#include "fsm/builder/uterus_generator.hpp"

int main(int argc, char** argv) {
  if (argc != 2 || std::string(argv[1]) == "-h" || std::string(argv[1]) == "--help") {
    std::fprintf(argc == 2 ? stdout : stderr,
                 "usage: make-uterus OUTPUT_DIR\n"
                 "Writes the procedural uterus (body, fibroid, ovaries, ovarian ligaments,\n"
                 "fallopian tubes) as OBJ surfaces in cm and the scene OUTPUT_DIR/uterus.json.\n");
    return argc == 2 ? 0 : 2;
  }
  try {
    const std::string directory = argv[1];
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
