// A wide lens beyond the views (scripts/bench-widelens.sh runs it): AprilTag
// boards rendered through a 112-degree lens, not reaching the image corners.
//   widelens_bench render DIR [seed=1] [views=30] [spread=0.6] [dmin=450] [dmax=1000] [rmax=0.85]
//     images/, board.yaml, truth.cameramodel, truth.vnl (true corners)
//   widelens_bench score TRUTH MODEL CORNERS.vnl W H GRID_W GRID_H SPACING
//     projection error against the truth on a 64 x 48 grid (rotation fitted over the observed cells):
//     p50 / p95 / max over the whole image, the observed cells and the others. When MODEL carries the
//     projection uncertainty (clearfit calibrate without --no-uncertainty), a second line sets it beside the
//     error: the largest σ and its pixel, σ and the error at the four image corners, and error / σ over the
//     grid (σ bilinear from the model's nodes, for points at its distance; the error is the ray's, any distance).
#include <clearfit/camera/board.hpp>
#include <clearfit/camera/calibrate.hpp>
#include <clearfit/camera/projection_uncertainty.hpp>
#include <clearfit/camera/render_board.hpp>

#include <opencv2/imgcodecs.hpp>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <vector>

using namespace clearfit;
namespace fs = std::filesystem;

namespace {

// An equidistant-like fisheye (r = f theta, f 655 px) fitted by an OPENCV8 rational model over theta <= 76 deg:
// 112 degrees across 1280 px, 70 degrees at the image corners.
CameraModel wide_lens() {  // tests/camera/calibrate_test.cpp (WideLensExtrapolatesBeyondTheViews) uses it too
  return {"LENSMODEL_OPENCV8",
          {655.0, 656.0, 641.3, 478.6, 0.6243, 0.05934, 0.0005, -0.0003, 0.000452, 0.9563, 0.1827, 0.005247},
          1280, 960, {}, {}};
}

int render(const fs::path& dir, unsigned seed, int views, double spread, double dmin, double dmax, double rmax) {
  const Board board = make_board({"tag36h11", 6, 8, 30, 30, 0});
  fs::create_directories(dir / "images");
  write_board(board, dir / "board.yaml");
  const CameraModel truth = wide_lens();
  write_cameramodel(truth, dir / "truth.cameramodel");
  const CalibrationGrid grid = CalibrationGrid::of(board);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0, 1);
  const double deg = std::numbers::pi / 180;
  const Eigen::Vector3d centre_in_board(0.5 * (grid.width - 1) * grid.spacing_mm, 0.5 * (grid.height - 1) * grid.spacing_mm, 0);
  const RayGrid rays = unproject_image(truth, 1);
  std::vector<BoardObservation> truths;
  int k = 0;
  for (int attempts = 0; k < views && attempts < 100000; ++attempts) {
    // Board centre within the central 60 % of the image, 450-1000 mm, tilted 10-45 degrees.
    const Vec2 q(truth.width * (0.5 + spread * (u01(rng) - 0.5)), truth.height * (0.5 + spread * (u01(rng) - 0.5)));
    const Vec3 ray = truth.unproject(q);
    const double distance = dmin + u01(rng) * (dmax - dmin), tilt = (10 + 35 * u01(rng)) * deg;
    const double axis_angle = u01(rng) * 2 * std::numbers::pi, spin = (u01(rng) - 0.5) * 60 * deg;
    Rigid3 pose;
    pose.rotation = (Eigen::AngleAxisd(tilt, Eigen::Vector3d(std::cos(axis_angle), std::sin(axis_angle), 0)) *
                     Eigen::AngleAxisd(spin, Eigen::Vector3d::UnitZ()))
                        .toRotationMatrix();
    pose.translation = ray.normalized() * distance - pose.rotation * centre_in_board;
    const auto tc = true_corners(board, truth, pose, 8);
    // At least 60 % of the corners in the image, none beyond rmax of the half diagonal from the centre.
    int inside = 0;
    bool far = false;
    const Vec2 centre(0.5 * (truth.width - 1), 0.5 * (truth.height - 1));
    for (const auto& c : tc)
      if (c.z() > 0) {
        ++inside;
        far |= (c.head<2>() - centre).norm() > rmax * centre.norm();
      }
    if (inside < 0.6 * static_cast<double>(tc.size()) || far) continue;
    RenderOptions ro;
    ro.noise_sigma = 2;
    ro.blur_sigma_px = 0.5;
    ro.seed = seed * 1000 + k + 1;
    ro.supersample = 3;
    char name[64];
    std::snprintf(name, sizeof name, "view%03d.png", k);
    cv::imwrite((dir / "images" / name).string(), render_board(board, truth, pose, ro, &rays));
    BoardObservation t;
    t.image = std::string("images/") + name;
    t.width = truth.width;
    t.height = truth.height;
    t.corners = tc;
    truths.push_back(t);
    ++k;
  }
  write_corners_levels_vnl(truths, dir / "truth.vnl");
  std::printf("rendered %d views to %s\n", k, dir.c_str());
  return 0;
}

double pct(std::vector<double> v, double p) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p * (v.size() - 1) + 0.5))];
}

/// The projection uncertainty beside the error against the truth (score's second line).
void print_uncertainty(const ProjectionUncertainty& u, int W, int H, const std::vector<double>& d, const std::vector<int>& observed,
                       const std::vector<Vec2>& corners, const std::vector<double>& at_corners) {
  const auto samples = uncertainty_sample_pixels(u.layout, u.nx, u.ny, W, H);
  const auto top = std::max_element(u.px.begin(), u.px.end());
  const Vec2 top_at = samples[static_cast<std::size_t>(top - u.px.begin())];
  std::printf("  uncertainty at %.0f mm: largest %.3f px at (%.0f, %.0f); image corners sigma", u.distance_mm, *top, top_at.x(), top_at.y());
  for (const Vec2& c : corners) std::printf(" %.3f", u.at(c, W, H));
  std::printf(" px, error");
  for (double e : at_corners) std::printf(" %.3f", e);
  const int nx = 64, ny = 48;
  std::vector<double> obs, unobs;
  for (int cy = 0; cy < ny; ++cy)
    for (int cx = 0; cx < nx; ++cx) {
      const std::size_t k = static_cast<std::size_t>(cy) * nx + cx;
      const double sigma = u.at(Vec2((cx + 0.5) * W / nx - 0.5, (cy + 0.5) * H / ny - 0.5), W, H);
      (observed[k] ? obs : unobs).push_back(std::isfinite(d[k]) ? d[k] / sigma : 1e9);
    }
  std::printf(" px | error/sigma: observed p50 %.2f p95 %.2f max %.2f, unobserved p50 %.2f p95 %.2f max %.2f\n", pct(obs, 0.5),
              pct(obs, 0.95), pct(obs, 1), pct(unobs, 0.5), pct(unobs, 0.95), pct(unobs, 1));
}

int score(char** argv) {
  const CameraModel truth = read_cameramodel(argv[2]);
  const CameraModel model = read_cameramodel(argv[3]);
  const int W = std::stoi(argv[5]), H = std::stoi(argv[6]);
  const CalibrationGrid grid{std::stoi(argv[7]), std::stoi(argv[8]), std::stod(argv[9])};
  const auto views = read_corners_vnl(argv[4], grid, W, H);
  const int nx = 64, ny = 48;
  std::vector<int> observed(nx * ny, 0);
  for (const auto& v : views)
    for (const auto& c : v.corners)
      if (c.z() >= 0) {
        const int cx = std::clamp(static_cast<int>((c.x() + 0.5) / W * nx), 0, nx - 1);
        const int cy = std::clamp(static_cast<int>((c.y() + 0.5) / H * ny), 0, ny - 1);
        ++observed[cy * nx + cx];
      }
  const std::vector<Vec2> corners{Vec2(0, 0), Vec2(W - 1.0, 0), Vec2(0, H - 1.0), Vec2(W - 1.0, H - 1.0)};
  auto d = projection_difference_grid(truth, model, nx, ny, observed, corners);
  const std::vector<double> at_corners(d.end() - 4, d.end());
  d.resize(d.size() - 4);
  std::vector<double> all, obs, unobs;
  for (std::size_t k = 0; k < d.size(); ++k) {
    const double e = std::isfinite(d[k]) ? d[k] : 1e9;
    all.push_back(e);
    (observed[k] ? obs : unobs).push_back(e);
  }
  std::printf("%-40s whole p50 %.3f p95 %.3f max %.2f | observed (%zu cells) p50 %.3f p95 %.3f max %.3f | unobserved p50 %.3f p95 %.3f max %.2f\n",
              argv[3], pct(all, 0.5), pct(all, 0.95), pct(all, 1), obs.size(), pct(obs, 0.5), pct(obs, 0.95), pct(obs, 1),
              pct(unobs, 0.5), pct(unobs, 0.95), pct(unobs, 1));
  if (const auto u = read_projection_uncertainty(argv[3])) print_uncertainty(*u, W, H, d, observed, corners, at_corners);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (mode == "render" && argc >= 3)
    return render(argv[2], argc > 3 ? std::stoul(argv[3]) : 1u, argc > 4 ? std::stoi(argv[4]) : 30,
                  argc > 5 ? std::stod(argv[5]) : 0.6, argc > 6 ? std::stod(argv[6]) : 450, argc > 7 ? std::stod(argv[7]) : 1000, argc > 8 ? std::stod(argv[8]) : 0.85);
  if (mode == "score" && argc >= 10) return score(argv);
  std::fprintf(stderr, "usage: widelens_bench render DIR [seed] [views] | score TRUTH MODEL CORNERS W H GW GH SPACING\n");
  return 2;
}
