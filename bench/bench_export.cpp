// ParaView export: the cost of writing one state of the bundled uterus (spheres with links and
// tetrahedra, and the 6,233-vertex render surface) with fsm::VtkSeriesWriter, and its size. Not a
// real-time cost (the demo writes from the render thread at --export-hz), but it bounds how often
// a session can be recorded.

#include <benchmark/benchmark.h>

#include <filesystem>

#include "fsm/builder/builder.hpp"
#include "fsm/fsm.hpp"
#include "fsm_support/model_cache.hpp"

namespace {

using namespace fsm;
namespace fs = std::filesystem;

void BM_VtkExportUterusState(benchmark::State& state) {
  const TissueModel<double>& model = support::bundled_uterus(
      [](const std::string& s) { return build::build_model(s); }, "bench_export");
  const fs::path dir = fs::temp_directory_path() / "fsm_bench_export";
  fs::remove_all(dir);
  VtkSeriesWriter writer(dir.string(), model.spheres, &model.skin);
  const Positions<double> v = Positions<double>::Constant(model.spheres.num_nodes(), 3, 0.01);
  const Positions<double>& x = model.spheres.rest_positions();
  double t = 0;
  for (auto _ : state) {
    t += 1e-3;
    writer.write(t, x, v, v, &model.skin.rest.vertices);
  }
  std::uintmax_t bytes = 0;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".vtu") bytes += e.file_size();
  state.counters["MB_per_state"] = double(bytes) / 1e6 / double(writer.states());
  state.counters["spheres"] = double(model.spheres.num_nodes());
  state.counters["surface_vertices"] = double(model.skin.num_vertices());
  fs::remove_all(dir);
}
BENCHMARK(BM_VtkExportUterusState)->Unit(benchmark::kMillisecond);

}  // namespace
