// Refraction map: exact against adaptive (1 µm) on the wristband and on a
// random freeform shell (shell:6, not tuned on) at 640x480 and 1920x1080,
// with counters for the error against the exact trace (p99, max, µm), the
// ratio to the floor (two batched ray casts per traced pixel, measured at
// set-up) and the share of pixels traced. The full sweep is
// `clearfit bench map`; scenes and the floor come from map_scenes.hpp.
//   map_bench --benchmark_filter=1920
#include "map_scenes.hpp"

#include <benchmark/benchmark.h>
#include <malloc.h>

#include <map>

namespace clearfit::bench {
namespace {

constexpr int kSizes[][2] = {{640, 480}, {1920, 1080}};
const char* const kShapes[] = {"band", "shell:6"};

struct Setup {
  std::unique_ptr<Scene> scene;
  CameraModel camera;
  Rigid3 pose;
  RefractionMap exact;
  Floor floor;
};

const Setup& setup(int shape, int size) {
  static std::map<std::pair<int, int>, Setup> cache;
  auto [it, inserted] = cache.try_emplace(std::pair(shape, size));
  Setup& s = it->second;
  if (inserted) {
    s.scene = make_scene(kShapes[shape]);
    s.camera = make_camera(kSizes[size][0], kSizes[size][1]);
    s.pose = frame_part(s.scene->mesh, s.camera);
    s.exact = compute_refraction_map(s.scene->trace(), s.camera, s.pose);
    s.floor = measure_floor(*s.scene, unproject_image(s.camera, 1), s.pose, s.exact, MapOptions{}.indices, 3);
  }
  return s;
}

void Map(benchmark::State& state) {
  const Setup& s = setup(static_cast<int>(state.range(2)), static_cast<int>(state.range(0)));
  MapOptions opt;
  const bool adaptive = state.range(1) == 1;
  if (adaptive) opt.mode = MapOptions::Mode::adaptive, opt.tolerance_um = 1.0;
  RefractionMap map;
  double total_ms = 0;
  for (auto _ : state) {
    map = compute_refraction_map(s.scene->trace(), s.camera, s.pose, opt);
    total_ms += map.stats.total_ms;
    benchmark::DoNotOptimize(map.status.data());
  }
  const MapError e = compare_maps(map, s.exact);
  const double mean_ms = total_ms / static_cast<double>(state.iterations());
  state.counters["x_floor"] = mean_ms / s.floor.ms;
  state.counters["floor_ms"] = s.floor.ms;
  state.counters["p99_um"] = e.p99_um;
  state.counters["max_um"] = e.max_um;
  state.counters["vdiff"] = static_cast<double>(e.validity_diff);
  state.counters["traced%"] = 100.0 * static_cast<double>(map.stats.traced) / static_cast<double>(map.stats.pixels);
  state.SetLabel(std::string(kShapes[state.range(2)]) + " " + std::to_string(kSizes[state.range(0)][0]) + "x" +
                 std::to_string(kSizes[state.range(0)][1]) + (adaptive ? " adaptive:1" : " exact"));
}
BENCHMARK(Map)
    ->ArgsProduct({{0, 1}, {0, 1}, {0, 1}})
    ->ArgNames({"size", "adaptive", "shape"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(1.0);

}  // namespace
}  // namespace clearfit::bench

int main(int argc, char** argv) {
  // Keep freed memory in the process (as `clearfit bench map` does): on some
  // VMs (Firecracker) a first touch of fresh memory costs ~6 ms/MB, which
  // would swamp the maps' run time.
  mallopt(M_MMAP_THRESHOLD, 1 << 30);
  mallopt(M_TRIM_THRESHOLD, -1);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
