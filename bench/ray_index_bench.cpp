// Ray index: build time and first-hit throughput (Mrays/s counter) of the
// Embree and CGAL backends on a bumpy height field of ~20k / 200k / 1M
// triangles, with camera-coherent rays (a pinhole camera's image rays in
// row-major 8x8 tiles) and random rays, on one thread and on all threads.
// The Embree variants (single rays, 16-ray packets, streams; vertex guards
// on/off; build quality) come from the private backend header.
//   ray_index_bench --benchmark_filter=Trace1Thread
#include <clearfit/geometry/ray_index.hpp>

#include <clearfit/geometry/ray_index_embree.hpp>

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <cmath>
#include <map>
#include <memory>
#include <random>

namespace clearfit {
namespace {

constexpr int kGrid[] = {100, 316, 707};  // 2·n² triangles: 20k, 200k, 1M

// z = bumps over [-50, 50]² mm: the kind of surface a wearable's skin side is.
const Mesh& height_field(int n) {
  static std::map<int, Mesh> cache;
  auto [it, inserted] = cache.try_emplace(n);
  Mesh& m = it->second;
  if (inserted) {
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) {
        const double x = -50 + 100.0 * i / n, y = -50 + 100.0 * j / n;
        m.vertices.emplace_back(x, y, 2 * std::sin(x / 7) * std::cos(y / 5) + 0.5 * std::sin(x / 1.3 + y / 2.1));
      }
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
        m.faces.push_back({a, b, c});
        m.faces.push_back({a, c, d});
      }
    m.file_face.resize(m.faces.size());
    for (size_t f = 0; f < m.faces.size(); ++f) m.file_face[f] = static_cast<int>(f);
  }
  return m;
}
const CornerNormals& normals_of(int n) {
  static std::map<int, CornerNormals> cache;
  auto it = cache.find(n);
  if (it == cache.end()) it = cache.emplace(n, compute_corner_normals(height_field(n))).first;
  return it->second;
}

// Variants: 0-2 Embree single/packet16/stream (stream is the default), 3 and
// 4 the default without vertex guards / with a medium-quality build, 5 CGAL.
constexpr const char* kVariant[] = {"embree_single", "embree_packet16", "embree_stream", "embree_noguard",
                                    "embree_medium_build", "cgal"};
std::unique_ptr<RayIndex> build(int grid, int variant) {
  const Mesh& m = height_field(grid);
  if (variant == 5) return make_ray_index(m, RayBackend::cgal_aabb, &normals_of(grid));
  EmbreeOptions o;
  o.mode = variant == 0   ? EmbreeOptions::Mode::single
           : variant == 1 ? EmbreeOptions::Mode::packet16
                          : EmbreeOptions::Mode::stream;
  o.vertex_guards = variant != 3;
  o.high_quality_build = variant != 4;
  return make_embree_ray_index(m, o, &normals_of(grid));
}
const RayIndex& cached(int grid, int variant) {
  static std::map<std::pair<int, int>, std::unique_ptr<RayIndex>> cache;
  auto& p = cache[{grid, variant}];
  if (!p) p = build(grid, variant);
  return *p;
}

// Camera at z = 150 mm looking down (-z), 512 x 512 pixels covering the
// field, rays ordered in row-major 8x8 tiles; or random rays from a box above
// to random points of the field.
std::vector<Ray> make_rays(bool camera, int count_side) {
  std::vector<Ray> rays;
  rays.reserve(static_cast<size_t>(count_side) * count_side);
  if (camera) {
    const double f = count_side / 2 / std::tan(0.33);  // ~38° half field of view
    for (int ty = 0; ty < count_side; ty += 8)
      for (int tx = 0; tx < count_side; tx += 8)
        for (int y = ty; y < ty + 8; ++y)
          for (int x = tx; x < tx + 8; ++x)
            rays.push_back({Vec3(0, 0, 150), Vec3((x - count_side / 2 + 0.5) / f, (y - count_side / 2 + 0.5) / f, -1)});
  } else {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0, 1);
    for (int i = 0; i < count_side * count_side; ++i) {
      const Vec3 o(-60 + 120 * u(rng), -60 + 120 * u(rng), 20 + 130 * u(rng));
      const Vec3 target(-50 + 100 * u(rng), -50 + 100 * u(rng), 0);
      rays.push_back({o, target - o});
    }
  }
  return rays;
}

void Build(benchmark::State& state) {
  const int grid = kGrid[state.range(0)], variant = static_cast<int>(state.range(1));
  height_field(grid), normals_of(grid);
  for (auto _ : state) benchmark::DoNotOptimize(build(grid, variant));
  state.SetLabel(std::string(kVariant[variant]) + " " + std::to_string(height_field(grid).num_faces()) + " tris");
}

void Trace(benchmark::State& state) {
  const int grid = kGrid[state.range(0)], variant = static_cast<int>(state.range(1));
  const bool camera = state.range(2) == 0, one_thread = state.range(3) == 1;
  const RayIndex& index = cached(grid, variant);
  const std::vector<Ray> rays = make_rays(camera, variant == 5 ? 128 : 512);
  std::vector<RayHit> hits(rays.size());
  std::unique_ptr<tbb::global_control> limit;
  if (one_thread) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, 1);
  for (auto _ : state) {
    index.intersect(rays, hits);
    benchmark::ClobberMemory();
  }
  size_t n_hit = 0;
  for (const RayHit& h : hits) n_hit += h.face >= 0;
  state.counters["Mrays/s"] = benchmark::Counter(1e-6 * static_cast<double>(rays.size()),
                                                 benchmark::Counter::kIsIterationInvariantRate);
  state.counters["hit%"] = 100.0 * n_hit / rays.size();
  state.SetLabel(std::string(kVariant[variant]) + " " + std::to_string(height_field(grid).num_faces()) + " tris, " +
                 (camera ? "camera" : "random") + (one_thread ? ", 1 thread" : ", all threads"));
}

void BuildArgs(benchmark::internal::Benchmark* b) {
  for (int size = 0; size < 3; ++size)
    for (int variant : {2, 4, 5}) b->Args({size, variant});
  b->Unit(benchmark::kMillisecond)->Iterations(1);
}
// Embree (default: stream) and CGAL at every size; the other Embree variants
// at 200k triangles. One thread: rates per CPU second of the calling thread
// (fair on a shared machine); all threads: per wall-clock second.
void TraceArgs(benchmark::internal::Benchmark* b, int one_thread) {
  for (int size = 0; size < 3; ++size)
    for (int variant = 0; variant < 6; ++variant)
      if (variant == 2 || variant == 5 || size == 1)
        for (int camera = 0; camera < 2; ++camera) b->Args({size, variant, camera, one_thread});
  b->Unit(benchmark::kMillisecond)->MinTime(0.3);
}
BENCHMARK(Build)->Apply(BuildArgs);
BENCHMARK(Trace)->Apply([](auto* b) { TraceArgs(b, 1); })->Name("Trace1Thread");
BENCHMARK(Trace)->Apply([](auto* b) { TraceArgs(b, 0); })->Name("TraceAllThreads")->UseRealTime();

}  // namespace
}  // namespace clearfit

BENCHMARK_MAIN();
