// fsm-build: builds a scene into a model file and prints a Table-1-like report.
//
//   fsm-build SCENE.json -o MODEL.fsm [--json] [--quiet]
//
// Progress goes to standard error; the report (text, or JSON with --json) to standard output.
// Exit status: 0 built, 1 bad input (the message names file, part and reason), 2 bad usage.

#include <cstdio>
#include <cstring>
#include <string>

#include "fsm/builder/builder.hpp"
#include "fsm/model_file.hpp"

namespace {
[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr,
               "fsm-build: %s\nusage: fsm-build SCENE.json -o MODEL.fsm [--json] [--quiet]\n", why);
  std::exit(2);
}
}  // namespace

int main(int argc, char** argv) {
  std::string scene, output;
  bool json = false, quiet = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-o" || a == "--output") {
      if (++i >= argc) usage("missing path after -o");
      output = argv[i];
    } else if (a == "--json") {
      json = true;
    } else if (a == "--quiet") {
      quiet = true;
    } else if (a == "-h" || a == "--help") {
      usage("help");
    } else if (!a.empty() && a[0] == '-') {
      usage(("unknown option " + a).c_str());
    } else if (scene.empty()) {
      scene = a;
    } else {
      usage("more than one scene given");
    }
  }
  if (scene.empty()) usage("no scene given");
  if (output.empty()) usage("no output given (-o MODEL.fsm)");
  try {
    fsm::build::HybridTopologyBuilder builder(fsm::build::load_scene(scene));
    if (!quiet)
      builder.set_progress([](const std::string& part, const std::string& stage, double f) {
        std::fprintf(stderr, "[%3.0f%%] %s%s%s\n", 100 * f, part.c_str(), part.empty() ? "" : ": ",
                     stage.c_str());
      });
    const fsm::TissueModel<double> model = builder.build();
    fsm::save_model(output, model);
    const std::string report = json ? builder.report().json() + "\n" : builder.report().table();
    std::fputs(report.c_str(), stdout);
    if (!quiet) std::fprintf(stderr, "wrote %s\n", output.c_str());
    return 0;
  } catch (const fsm::Error& e) {
    std::fprintf(stderr, "fsm-build: %s\n", e.what());
    return 1;
  }
}
