// The builder's costs: the tetrahedral filling with each optimiser (time and element quality, the
// measurement behind the default), and whole-scene builds of the uterus with the hybrid topology
// against the paper's baselines (grid filling at three spacings, unequal-radius packing).

#include <benchmark/benchmark.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "fsm/builder/builder.hpp"
#include "fsm/builder/fillings.hpp"
#include "fsm_support/model_cache.hpp"

namespace fsm::bench {
namespace {

namespace fs = std::filesystem;
const std::string kData = support::source_data_dir();
const std::string kScene = kData + "/uterus/uterus.json";

void BM_TetraFilling(benchmark::State& state, const std::string& optimiser,
                     const std::string& which) {
  // The procedural body (smooth) and the VHF uterus wrapped from its walls (sharp creases where
  // the wrap meets itself); the latter only where the shared data exists.
  TriangleMesh<double> body;
  double r = 0.005;
  if (which == "body") {
    body = build::read_mesh(kData + "/uterus/body.obj", 0.01);
  } else {
    const std::string d = std::string(FSM_SHARED_DATA_DIR) + "/vhf-pelvis/";
    if (!fs::exists(d)) {
      state.SkipWithError("no shared data folder");
      return;
    }
    std::vector<TriangleMesh<double>> walls;
    for (const char* f : {"anterior_wall_of_uterus.obj", "posterior_wall_of_uterus.obj",
                          "cervix.obj", "cornua.obj"})
      walls.push_back(build::read_mesh(d + f));
    body = build::alpha_wrap(walls, 0.003, 0.0003);
    r = 0.003;
  }
  const auto metric = build::isotropic_metric(r);
  build::TetraFilling fill;
  for (auto _ : state) fill = build::fill_tetrahedral(body, *metric, optimiser, which);
  state.counters["spheres"] = double(fill.mesh.vertices.rows());
  state.counters["tetrahedra"] = double(fill.quality.tetrahedra);
  state.counters["q_1_3_pct"] = 100 * fill.quality.fraction_q_1_3;
  state.counters["q_mean"] = fill.quality.q_mean;
  state.counters["min_dihedral_deg"] = fill.quality.min_dihedral_deg;
}

// The uterus scene with every tetrahedral part refilled by a baseline.
void BM_UterusScene(benchmark::State& state, const std::string& topology, double grid_spacing_cm) {
  nlohmann::json scene;
  std::ifstream(kScene) >> scene;
  if (topology != "hybrid") {
    // The hybrid scene's anchors are sized for its spheres: a coarse grid or a packing (whose
    // centres keep away from the surface) may have no sphere in them. Hold the body by its lowest
    // 2.3 cm instead; the ovaries hang from it through their ligaments.
    scene["fixed"] = nlohmann::json::array(
        {{{"part", "body"}, {"box", {{"min", {-10, -10, -10}}, {"max", {10, 10, -1.5}}}}}});
  }
  for (auto& p : scene["parts"]) {
    if (p.contains("mesh"))
      p["mesh"] = (fs::path(kScene).parent_path() / p["mesh"].get<std::string>()).string();
    if (topology != "hybrid" && p["topology"] == "tetrahedral") {
      p["topology"] = topology;
      p.erase("metric");
      p.erase("optimiser");
      if (topology == "grid") p["grid"] = {{"neighbours", 6}, {"spacing", grid_spacing_cm}};
    }
  }
  const fs::path tmp = fs::temp_directory_path() /
                       ("fsm_bench_" + topology + std::to_string(grid_spacing_cm) + ".json");
  std::ofstream(tmp) << scene.dump();
  build::BuildReport report;
  for (auto _ : state) {
    try {
      const auto model = build::build_model(tmp.string(), &report);
      benchmark::DoNotOptimize(model.spheres.num_nodes());
    } catch (const Error& e) {
      state.SkipWithError(e.what());
      break;
    }
  }
  fs::remove(tmp);
  state.counters["spheres"] = double(report.spheres);
  state.counters["links"] = double(report.links);
}

const bool registered = [] {
  for (const std::string opt : {"none", "perturb", "exude", "lloyd", "odt", "odt_perturb"})
    for (const std::string which : {"body", "vhf_uterus"})
      benchmark::RegisterBenchmark(
          ("BM_TetraFilling/" + which + "/" + opt).c_str(),
          [opt, which](benchmark::State& s) { BM_TetraFilling(s, opt, which); })
          ->Unit(benchmark::kMillisecond)
          ->Iterations(3);
  benchmark::RegisterBenchmark("BM_UterusScene/hybrid",
                               [](benchmark::State& s) { BM_UterusScene(s, "hybrid", 0); })
      ->Unit(benchmark::kMillisecond)
      ->Iterations(3);
  for (double cm : {0.5, 0.3, 0.2})
    benchmark::RegisterBenchmark(
        ("BM_UterusScene/grid/spacing_mm:" + std::to_string(int(cm * 10))).c_str(),
        [cm](benchmark::State& s) { BM_UterusScene(s, "grid", cm); })
        ->Unit(benchmark::kMillisecond)
        ->Iterations(1);
  benchmark::RegisterBenchmark("BM_UterusScene/packing",
                               [](benchmark::State& s) { BM_UterusScene(s, "packing", 0); })
      ->Unit(benchmark::kMillisecond)
      ->Iterations(1);
  return true;
}();

}  // namespace
}  // namespace fsm::bench
