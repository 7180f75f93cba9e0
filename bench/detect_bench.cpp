// AprilTag board detection at 1920x1080: images per second for AprilTag alone,
// with straight-edge sub-pixel corners, and the lens-aware refinement, plus
// their corner error against the true projected corners (counters, px).
#include <clearfit/camera/board.hpp>
#include <clearfit/camera/detect.hpp>
#include <clearfit/camera/render_board.hpp>

#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <cmath>

namespace clearfit {
namespace {

struct Scene {
  CameraModel camera;
  Board board = make_board({"tag36h11", 8, 10, 20.0, 20.0, 0});
  Rigid3 cam_from_board;
  cv::Mat image;
  std::vector<Eigen::Vector3d> truth;
  Scene() {
    camera.lensmodel = "LENSMODEL_OPENCV8";
    camera.intrinsics = {1400, 1402, 955.3, 541.8, -0.3, 0.12, 5e-4, -3e-4, -0.02, 0, 0, 0};
    camera.width = 1920, camera.height = 1080;
    cam_from_board.rotation =
        (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitX()))
            .toRotationMatrix();
    cam_from_board.translation =
        Eigen::Vector3d(0, 0, 520) -
        cam_from_board.rotation * Eigen::Vector3d(board.width_mm() / 2, board.height_mm() / 2, 0);
    RenderOptions ro;
    ro.blur_sigma_px = 0.6;
    ro.noise_sigma = 2;
    ro.seed = 11;
    image = render_board(board, camera, cam_from_board, ro);
    truth = true_corners(board, camera, cam_from_board, 4);
  }
  double rms(const BoardObservation& o) const {
    double s = 0;
    int n = 0;
    for (std::size_t i = 0; i < truth.size(); ++i)
      if (truth[i].z() >= 0 && o.corners[i].z() >= 0)
        s += (o.corners[i] - truth[i]).head<2>().squaredNorm(), ++n;
    return n ? std::sqrt(s / n) : NAN;
  }
};

const Scene& scene() {
  static const Scene s;
  return s;
}

void BM_Detect(benchmark::State& state) {
  const Scene& s = scene();
  DetectOptions o;
  o.subpixel = state.range(0) != 0;
  o.quad_decimate = static_cast<float>(state.range(1));
  BoardObservation obs;
  for (auto _ : state) obs = detect_board(s.image, s.board, o, "bench");
  state.counters["images/s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["corners"] = obs.num_valid();
  state.counters["rms_px"] = s.rms(obs);
  state.SetLabel(o.subpixel ? "AprilTag + straight-edge corners" : "AprilTag corners");
}
BENCHMARK(BM_Detect)->Args({0, 2})->Args({1, 2})->Args({1, 1})->Args({1, 4})->Unit(benchmark::kMillisecond);

void BM_RefineLensAware(benchmark::State& state) {
  const Scene& s = scene();
  const BoardObservation obs = detect_board(s.image, s.board, {}, "bench");
  BoardObservation refined;
  for (auto _ : state) refined = refine_corners(s.image, obs, s.board, &s.camera);
  state.counters["images/s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["rms_px"] = s.rms(refined);
  state.counters["rms_before_px"] = s.rms(obs);
}
BENCHMARK(BM_RefineLensAware)->Unit(benchmark::kMillisecond);

void BM_RenderBoard(benchmark::State& state) {
  const Scene& s = scene();
  const RayGrid rays = unproject_image(s.camera, 1);
  for (auto _ : state) benchmark::DoNotOptimize(render_board(s.board, s.camera, s.cam_from_board, {}, &rays));
}
BENCHMARK(BM_RenderBoard)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace clearfit

BENCHMARK_MAIN();
