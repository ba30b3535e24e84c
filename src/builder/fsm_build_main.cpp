// fsm-build: builds a scene into a model file and prints a Table-1-like report.
//
//   fsm-build SCENE.json -o MODEL.fsm [--json] [--quiet] [--max-spheres N] [--max-elements N]
//             [--max-memory-gb G]
//
// The --max-* options replace the scene's resource budget (docs/builder.md).
// Progress goes to standard error; the report (text, or JSON with --json) to standard output.
// Exit status: 0 built, 1 bad input (the message names file, part and reason), 2 bad usage.

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>
#include <string>

#include "fsm/builder/builder.hpp"
#include "fsm/model_file.hpp"

namespace {
[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr,
               "fsm-build: %s\nusage: fsm-build SCENE.json -o MODEL.fsm [--json] [--quiet] "
               "[--max-spheres N] [--max-elements N] [--max-memory-gb G]\n",
               why);
  std::exit(2);
}
}  // namespace

int main(int argc, char** argv) {
  std::string scene, output;
  bool json = false, quiet = false;
  double max_spheres = 0, max_elements = 0, max_memory_gb = 0;  // 0: the scene's
  auto positive = [&](int& i, const char* what) {
    if (++i >= argc) usage((std::string("missing value after ") + what).c_str());
    char* end = nullptr;
    const double v = std::strtod(argv[i], &end);
    if (end == argv[i] || *end != '\0' || !(v > 0) || !std::isfinite(v))
      usage((std::string(what) + " needs a positive number, got '" + argv[i] + "'").c_str());
    return v;
  };
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-o" || a == "--output") {
      if (++i >= argc) usage("missing path after -o");
      output = argv[i];
    } else if (a == "--json") {
      json = true;
    } else if (a == "--quiet") {
      quiet = true;
    } else if (a == "--max-spheres") {
      max_spheres = positive(i, "--max-spheres");
    } else if (a == "--max-elements") {
      max_elements = positive(i, "--max-elements");
    } else if (a == "--max-memory-gb") {
      max_memory_gb = positive(i, "--max-memory-gb");
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
