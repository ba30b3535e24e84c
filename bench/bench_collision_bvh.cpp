// TriangleBvh: build and refit cost per face, ray cast (picking) and faces_near (surface contact)
// cost per query, on closed bumpy ellipsoids of about 2k, 12k and 100k faces (the size of an
// adult uterine body, 8 x 5.6 x 4.4 cm) and on the default uterus's render surfaces (all eight
// parts of data/uterus, 12,434 faces, read from the source tree).

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "fsm/collision/triangle_bvh.hpp"

namespace fsm::bench {
namespace {

using collision::TriangleBvh;

// A closed UV ellipsoid with semi-axes 40 x 28 x 22 mm, radii jittered by 5 %; `faces` is
// rounded to 4 r (r - 1) for r rings and 2 r sectors.
template <typename Scalar>
TriangleMesh<Scalar> ellipsoid(int faces) {
  const int rings = int(std::lround(std::sqrt(faces / 4.0))) + 1, sectors = 2 * rings;
  const double pi = 3.14159265358979323846;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  TriangleMesh<Scalar> m;
  const Index nv = 2 + (rings - 1) * sectors;
  m.vertices.resize(nv, 3);
  auto put = [&](Index i, double th, double ph) {
    const double r = 1 + 0.05 * u(rng);
    m.vertices.row(i) << Scalar(0.040 * r * std::sin(th) * std::cos(ph)),
        Scalar(0.028 * r * std::sin(th) * std::sin(ph)), Scalar(0.022 * r * std::cos(th));
  };
  put(0, 0, 0);
  for (int i = 1; i < rings; ++i)
    for (int s = 0; s < sectors; ++s)
      put(1 + (i - 1) * sectors + s, pi * i / rings, 2 * pi * s / sectors);
  put(nv - 1, pi, 0);
  auto ring = [&](int i, int s) { return Index(1 + (i - 1) * sectors + s % sectors); };
  m.faces.resize(2 * sectors * (rings - 1), 3);
  Index f = 0;
  for (int s = 0; s < sectors; ++s) m.faces.row(f++) << 0, ring(1, s), ring(1, s + 1);
  for (int i = 1; i < rings - 1; ++i)
    for (int s = 0; s < sectors; ++s) {
      m.faces.row(f++) << ring(i, s), ring(i + 1, s), ring(i + 1, s + 1);
      m.faces.row(f++) << ring(i, s), ring(i + 1, s + 1), ring(i, s + 1);
    }
  for (int s = 0; s < sectors; ++s)
    m.faces.row(f++) << nv - 1, ring(rings - 1, s + 1), ring(rings - 1, s);
  return m;
}

// All OBJ files of data/uterus concatenated (cm -> m), or an empty mesh if they are not there.
template <typename Scalar>
TriangleMesh<Scalar> uterus_surfaces() {
  const std::filesystem::path dir =
      std::filesystem::path(__FILE__).parent_path().parent_path() / "data" / "uterus";
  std::vector<double> v;
  std::vector<Index> f;
  std::error_code ec;
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec))
    if (entry.path().extension() == ".obj") files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  for (const auto& path : files) {
    std::ifstream in(path);
    const Index base = Index(v.size() / 3);
    for (std::string line; std::getline(in, line);) {
      std::istringstream ls(line);
      std::string tag;
      ls >> tag;
      if (tag == "v") {
        double x, y, z;
        ls >> x >> y >> z;
        v.insert(v.end(), {0.01 * x, 0.01 * y, 0.01 * z});
      } else if (tag == "f") {
        for (int k = 0; k < 3; ++k) {
          std::string word;
          ls >> word;
          f.push_back(base + Index(std::stol(word)) - 1);  // "i" or "i/t/n"
        }
      }
    }
  }
  TriangleMesh<Scalar> m;
  m.vertices = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(
                   v.data(), Index(v.size() / 3), 3)
                   .template cast<Scalar>();
  m.faces = Eigen::Map<const FaceArray>(f.data(), Index(f.size() / 3), 3);
  return m;
}

// Range argument: faces of the ellipsoid, or 0 for the uterus's surfaces.
template <typename Scalar>
const TriangleMesh<Scalar>& surface(int64_t faces) {
  static std::map<int64_t, TriangleMesh<Scalar>> cache;
  auto it = cache.find(faces);
  if (it == cache.end())
    it = cache.emplace(faces, faces ? ellipsoid<Scalar>(int(faces)) : uterus_surfaces<Scalar>())
             .first;
  return it->second;
}

// The surface moved as by skinning: a bend of a few mm and 0.2 mm of noise.
template <typename Scalar>
Positions<Scalar> deformed(const Positions<Scalar>& v) {
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0, 1);
  Positions<Scalar> out = v;
  for (Index i = 0; i < v.rows(); ++i) {
    const double x = double(v(i, 0));
    out(i, 2) += Scalar(0.004 * std::sin(60 * x) + 0.0002 * g(rng));
    out(i, 1) += Scalar(0.0002 * g(rng));
  }
  return out;
}

// Reports time per item as a counter `name` (seconds, inverted rate), and items/s.
void per_item(benchmark::State& state, double items_per_iteration, const char* name) {
  state.SetItemsProcessed(int64_t(double(state.iterations()) * items_per_iteration));
  state.counters[name] =
      benchmark::Counter(items_per_iteration, benchmark::Counter::kIsIterationInvariantRate |
                                                  benchmark::Counter::kInvert);
}

bool skip_if_missing(benchmark::State& state, Index faces) {
  if (faces > 0) return false;
  state.SkipWithError("data/uterus/*.obj not found next to the benchmark's source");
  return true;
}

template <typename Scalar>
void BM_Build(benchmark::State& state) {
  const auto& m = surface<Scalar>(state.range(0));
  if (skip_if_missing(state, m.num_faces())) return;
  TriangleBvh<Scalar> bvh(m.vertices, m.faces);  // warm-up
  for (auto _ : state) {
    bvh.build(m.vertices, m.faces);
    benchmark::DoNotOptimize(bvh.nodes().data());
  }
  state.counters["faces"] = double(m.num_faces());
  state.counters["depth"] = double(bvh.depth());
  per_item(state, double(m.num_faces()), "per_face");
}

template <typename Scalar>
void BM_Refit(benchmark::State& state) {
  const auto& m = surface<Scalar>(state.range(0));
  if (skip_if_missing(state, m.num_faces())) return;
  TriangleBvh<Scalar> bvh(m.vertices, m.faces);
  const Positions<Scalar> moved = deformed(m.vertices);
  bool flip = false;
  bvh.refit(moved);  // warm-up
  for (auto _ : state) {
    flip = !flip;
    benchmark::DoNotOptimize(bvh.refit(flip ? m.vertices : moved));
    benchmark::ClobberMemory();
  }
  state.counters["faces"] = double(m.num_faces());
  per_item(state, double(m.num_faces()), "per_face");
}

// Picking rays: from points 20-30 cm from the surface's centre (a laparoscope's distance) towards
// random points of the surface's bounding box; about half hit.
template <typename Scalar>
void BM_RayCast(benchmark::State& state) {
  const auto& m = surface<Scalar>(state.range(0));
  if (skip_if_missing(state, m.num_faces())) return;
  const TriangleBvh<Scalar> bvh(m.vertices, m.faces);
  const Vector3<Scalar> lo = bvh.nodes()[0].lo, hi = bvh.nodes()[0].hi;
  const Vector3<Scalar> mid = (lo + hi) / 2;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> g(0, 1);
  const int n = 4096;
  std::vector<Vector3<Scalar>> origins, directions;
  for (int i = 0; i < n; ++i) {
    const Vector3<double> away = Vector3<double>(g(rng), g(rng), g(rng)).normalized();
    origins.push_back(mid + (away * (0.2 + 0.1 * u(rng))).template cast<Scalar>());
    Vector3<Scalar> target;
    for (int k = 0; k < 3; ++k) target[k] = lo[k] + Scalar(u(rng)) * (hi[k] - lo[k]);
    directions.push_back(target - origins.back());
  }
  int hits = 0;
  for (int i = 0; i < n; ++i)
    hits += bvh.ray_cast(origins[size_t(i)], directions[size_t(i)]) ? 1 : 0;
  for (auto _ : state)
    for (int i = 0; i < n; ++i)
      benchmark::DoNotOptimize(bvh.ray_cast(origins[size_t(i)], directions[size_t(i)]));
  state.counters["faces"] = double(m.num_faces());
  state.counters["hit_fraction"] = double(hits) / n;
  per_item(state, n, "per_query");
}

// Contact queries: spheres of 3 mm radius (a filling sphere of the 6.2 mm lattice) centred within
// 3 mm of a random surface point.
template <typename Scalar>
void BM_FacesNear(benchmark::State& state) {
  const auto& m = surface<Scalar>(state.range(0));
  if (skip_if_missing(state, m.num_faces())) return;
  const TriangleBvh<Scalar> bvh(m.vertices, m.faces);
  std::mt19937 rng(6);
  std::uniform_int_distribution<Index> face(0, m.num_faces() - 1);
  std::uniform_real_distribution<double> u(-1, 1);
  const int n = 4096;
  const Scalar radius = Scalar(0.003);
  std::vector<Vector3<Scalar>> centres;
  for (int i = 0; i < n; ++i) {
    const Index f = face(rng);
    Vector3<Scalar> c = (m.vertices.row(m.faces(f, 0)) + m.vertices.row(m.faces(f, 1)) +
                         m.vertices.row(m.faces(f, 2)))
                            .transpose() /
                        Scalar(3);
    c += (0.003 * Vector3<double>(u(rng), u(rng), u(rng))).template cast<Scalar>();
    centres.push_back(c);
  }
  std::vector<Index> out(256);
  double found = 0;
  for (const auto& c : centres)
    found += double(bvh.faces_near(c, radius, out.data(), Index(out.size())));
  for (auto _ : state)
    for (const auto& c : centres)
      benchmark::DoNotOptimize(bvh.faces_near(c, radius, out.data(), Index(out.size())));
  state.counters["faces"] = double(m.num_faces());
  state.counters["found_per_query"] = found / n;
  per_item(state, n, "per_query");
}

// Brute force over all faces, for scale: what the tree saves per ray.
template <typename Scalar>
void BM_RayCastBruteForce(benchmark::State& state) {
  const auto& m = surface<Scalar>(state.range(0));
  if (skip_if_missing(state, m.num_faces())) return;
  const Vector3<Scalar> o(Scalar(0.25), Scalar(0.05), Scalar(0.02));
  const Vector3<Scalar> d = (-o).normalized();
  for (auto _ : state) {
    Scalar best = std::numeric_limits<Scalar>::infinity();
    for (Index f = 0; f < m.num_faces(); ++f) {
      const auto hit = collision::intersect_ray_triangle<Scalar>(
          o, d, m.vertices.row(m.faces(f, 0)).transpose(),
          m.vertices.row(m.faces(f, 1)).transpose(), m.vertices.row(m.faces(f, 2)).transpose(),
          best);
      if (hit) best = hit->distance;
    }
    benchmark::DoNotOptimize(best);
  }
  state.counters["faces"] = double(m.num_faces());
  per_item(state, 1, "per_query");
}

void sizes(benchmark::internal::Benchmark* b) {
  for (int64_t faces : {2000, 12000, 100000, 0}) b->Arg(faces);
  b->ArgName("faces")->MinWarmUpTime(0.05);
}

BENCHMARK_TEMPLATE(BM_Build, double)->Apply(sizes)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_Build, float)->Apply(sizes)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_Refit, double)->Apply(sizes)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_Refit, float)->Apply(sizes)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_RayCast, double)->Apply(sizes)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_RayCast, float)->Apply(sizes)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_FacesNear, double)->Apply(sizes)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_FacesNear, float)->Apply(sizes)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_RayCastBruteForce, double)
    ->Arg(12000)
    ->ArgName("faces")
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace fsm::bench
