// fsm-build: builds a scene into a model file and prints a Table-1-like report.
//
//   fsm-build SCENE.json -o MODEL.fsm [--json] [-q|--quiet] [--max-spheres N] [--max-elements N]
//             [--max-memory-gb G] [--help] [--version]
//
// The --max-* options replace the scene's resource budget (docs/builder.md).
// Progress goes to standard error; the report (text, or JSON with --json) to standard output.
// Exit status: 0 built, 1 bad input (the message names file, part and reason), 2 bad usage.

#include <cstdio>
#include <new>
#include <string>

#include "fsm/builder/builder.hpp"
#include "fsm/model_file.hpp"
#include "fsm_support/cli.hpp"

int main(int argc, char** argv) {
  CLI::App app(
      "Builds a scene (docs/scene.md) into a model file (docs/model_file.md) and prints a "
      "Table-1-like report.",
      "fsm-build");
  fsm::support::add_version_flag(app);
  std::string scene, output;
  bool json = false, quiet = false;
  double max_spheres = 0, max_elements = 0, max_memory_gb = 0;  // 0: the scene's
  app.add_option("scene", scene, "the scene file (JSON)")->required();
  app.add_option("-o,--output", output, "the model file to write")->required();
  app.add_flag("--json", json, "print the report as JSON (warnings also to stderr)");
  app.add_flag("-q,--quiet", quiet, "no progress on stderr");
  app.add_option("--max-spheres", max_spheres, "replace the scene's sphere budget")
      ->check(fsm::support::positive_number());
  app.add_option("--max-elements", max_elements, "replace the scene's element budget")
      ->check(fsm::support::positive_number());
  app.add_option("--max-memory-gb", max_memory_gb, "replace the scene's memory budget (GB)")
      ->check(fsm::support::positive_number());
  if (const int status = fsm::support::parse_command_line(app, argc, argv); status >= 0)
    return status;
  try {
    fsm::build::HybridTopologyBuilder builder(fsm::build::load_scene(scene));
    fsm::build::BuildLimits limits = builder.scene().limits;
    if (max_spheres > 0) limits.spheres = max_spheres;
    if (max_elements > 0) limits.elements = max_elements;
    if (max_memory_gb > 0) limits.memory_bytes = max_memory_gb * 1e9;
    builder.set_limits(limits);
    if (!quiet)
      builder.set_progress([](const std::string& part, const std::string& stage, double f) {
        std::fprintf(stderr, "[%3.0f%%] %s%s%s\n", 100 * f, part.c_str(), part.empty() ? "" : ": ",
                     stage.c_str());
      });
    const fsm::TissueModel<double> model = builder.build();
    fsm::save_model(output, model);
    const std::string report = json ? builder.report().json() + "\n" : builder.report().table();
    std::fputs(report.c_str(), stdout);
    if (json)  // the text table prints them; with --json they also go to stderr
      for (const std::string& w : builder.report().warnings())
        std::fprintf(stderr, "fsm-build: warning: %s\n", w.c_str());
    if (!quiet) std::fprintf(stderr, "wrote %s\n", output.c_str());
    return 0;
  } catch (const fsm::Error& e) {
    std::fprintf(stderr, "fsm-build: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "fsm-build: %s: out of memory (raise no limit; check the scene's sizes)\n",
                 scene.c_str());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fsm-build: %s: %s\n", scene.c_str(), e.what());
    return 1;
  }
}
