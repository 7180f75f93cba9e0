// calibrate_camera against synthetic ground truth (a known OPENCV8 lens,
// known board poses, Gaussian noise of known sigma, fixed seeds) and against
// mrcal's own tools (mrcal-calibrate-cameras and the Python mrcal module via
// /usr/bin/python3, run once for the whole program).
#include <clearfit/camera/calibrate.hpp>
#include <clearfit/camera/projection_uncertainty.hpp>
#include <clearfit/error.hpp>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numeric>
#include <random>
#include <sstream>

namespace clearfit {
namespace {

namespace fs = std::filesystem;

CameraModel true_lens() {
  CameraModel m;
  m.lensmodel = "LENSMODEL_OPENCV8";
  m.width = 1280;
  m.height = 960;
  m.intrinsics = {1000.0, 1002.0, 641.3, 478.6, -0.30, 0.10, 0.0010, -0.0005, -0.02, 0.02, 0.01, 0.0};
  return m;
}

const CalibrationGrid kGrid{10, 10, 30.0};

struct Stats {
  double centre = 0, worst = 0, rms = 0;
};
// Projection error against the truth over the cells with observations.
Stats error_vs_truth(const CameraModel& truth, const CameraModel& model, const CalibrationResult& r) {
  const auto d = projection_difference_grid(truth, model, r.coverage_cells_x, r.coverage_cells_y, r.coverage);
  Stats s;
  int n = 0;
  for (std::size_t k = 0; k < d.size(); ++k)
    if (r.coverage[k] > 0) {
      s.worst = std::max(s.worst, d[k]);
      s.rms += d[k] * d[k];
      ++n;
    }
  s.rms = std::sqrt(s.rms / n);
  // The centre cell of an odd grid (rotation fitted over the observed cells).
  const auto c = projection_difference_grid(
      truth, model, 2 * r.coverage_cells_x + 1, 2 * r.coverage_cells_y + 1,
      std::vector<int>((2 * r.coverage_cells_x + 1) * (2 * r.coverage_cells_y + 1), 1));
  s.centre = c[c.size() / 2];
  return s;
}

// One scratch folder for the program, removed at exit unless a test failed.
fs::path scratch() {
  struct Dir {
    fs::path path;
    Dir() {
      std::string templ = (fs::temp_directory_path() / "clearfit_calibrate_test_XXXXXX").string();
      if (!mkdtemp(templ.data())) throw std::runtime_error("mkdtemp");
      path = templ;
    }
    ~Dir() {
      std::error_code ec;
      if (!::testing::UnitTest::GetInstance()->Failed()) fs::remove_all(path, ec);
    }
  };
  static const Dir dir;
  return dir.path;
}

std::string run(const std::string& command) {
  std::string out;
  FILE* p = popen((command + " 2>&1").c_str(), "r");
  if (!p) throw std::runtime_error("popen " + command);
  char buf[4096];
  while (std::size_t n = fread(buf, 1, sizeof buf, p)) out.append(buf, n);
  const int rc = pclose(p);
  if (rc != 0) throw std::runtime_error(command + " failed (" + std::to_string(rc) + "):\n" + out);
  return out;
}

// mrcal-calibrate-cameras in `dir` with `args`. The tool's solve is not
// repeatable run to run on an ill-conditioned set (the wide lens's corners.vnl
// gave a board warp of 1e-6 in one run and 6e-4 in the next), and about one
// run in four on that set stops in its valid-intrinsics region with "Cannot
// compute the uncertainty: factorization computation failed" (twice in a row
// once). A run that stops there is retried, up to five runs in all.
void run_mrcal_tool(const fs::path& dir, const std::string& args) {
  const std::string command =
      "cd " + dir.string() + " && /usr/bin/python3 /usr/bin/mrcal-calibrate-cameras " + args + " 'frame*.png'";
  for (int attempt = 1;; ++attempt) {
    try {
      run(command);
      return;
    } catch (const std::runtime_error& e) {
      if (attempt == 5 || std::string(e.what()).find("factorization computation failed") == std::string::npos) throw;
      std::printf("mrcal-calibrate-cameras stopped in its uncertainty factorization (run %d); running it again\n",
                  attempt);
    }
  }
}

// One calibration of the shared data set (30 views, sigma 0.3 px, seed 7),
// ours and mrcal's tool's, computed once.
struct Shared {
  CameraModel truth = true_lens();
  std::vector<BoardObservation> views;
  std::vector<Rigid3> poses;
  CalibrationResult ours;
  fs::path ours_path, mrcal_path, vnl;
  double sigma = 0.3;
};
const Shared& shared() {
  static const std::unique_ptr<Shared> s = [] {
    auto s = std::make_unique<Shared>();
    SyntheticViewsOptions o;
    o.views = 30;
    o.noise_px = s->sigma;
    o.seed = 7;
    std::printf("synthetic views: seed %u, %d views, sigma %.2f px\n", o.seed, o.views, o.noise_px);
    s->views = synthesize_views(s->truth, kGrid, o, &s->poses);
    s->ours = calibrate_camera(s->views, kGrid);
    s->ours_path = scratch() / "ours.cameramodel";
    write_cameramodel(s->ours.model, s->ours_path);
    s->vnl = scratch() / "corners.vnl";
    write_corners_levels_vnl(s->views, s->vnl);
    const fs::path outdir = scratch() / "mrcal";
    fs::create_directories(outdir);
    run_mrcal_tool(scratch(),
                   "--corners-cache corners.vnl --lensmodel LENSMODEL_OPENCV8 --focal 1000 --imagersize 1280 960 "
                   "--object-spacing 30 --object-width-n 10 --object-height-n 10 --outdir mrcal");
    s->mrcal_path = outdir / "camera-0.cameramodel";
    return s;
  }();
  return *s;
}

TEST(Calibrate, RecoversKnownOpencv8Lens) {
  const Shared& s = shared();
  const CalibrationResult& r = s.ours;
  EXPECT_EQ(r.model.lensmodel, "LENSMODEL_OPENCV8");
  // 2n residual coordinates of sigma each, P fitted parameters:
  // rms = sigma sqrt(1 - P / 2n).
  const int n = r.corners_used, p = 12 + 6 * 30 + 2;
  const double expected_rms = s.sigma * std::sqrt(1.0 - double(p) / (2.0 * n));
  std::printf("rms %.4f px (expected %.4f), corners %d, outliers %d, solve %.3f s, uncertainty %.3f s\n",
              r.rms_px, expected_rms, n, r.outliers, r.solve_seconds, r.uncertainty_seconds);
  EXPECT_NEAR(r.rms_px, expected_rms, 0.03 * expected_rms);
  // mrcal's regularisation does not bias this lens (small distortions): its sizing is kept.
  EXPECT_EQ(r.corner_weight_scale, 1.0);
  const Stats e = error_vs_truth(s.truth, r.model, r);
  std::printf("projection error vs truth: centre %.4f, rms %.4f, worst %.4f px\n", e.centre, e.rms, e.worst);
  EXPECT_LT(e.worst, 0.6);
  EXPECT_LT(e.rms, 0.2);
  EXPECT_LT(e.centre, 0.1);
  // Consistent with the noise: the error is within a few predicted standard
  // deviations (uncertainty at the board distance) everywhere observed.
  // At the nodes of the uncertainty's grid, edge to edge (the rotation fitted over 16 x 12 cell centres).
  ASSERT_EQ(r.uncertainty_nodes_x, 17);
  ASSERT_EQ(r.uncertainty_nodes_y, 13);
  ASSERT_EQ(r.uncertainty_px.size(), std::size_t(17 * 13));
  const auto nodes = uncertainty_sample_pixels(ProjectionUncertainty::Layout::nodes, 17, 13, r.model.width, r.model.height);
  const auto grid_and_nodes = projection_difference_grid(s.truth, r.model, 16, 12, std::vector<int>(16 * 12, 1), nodes);
  const std::vector<double> d(grid_and_nodes.begin() + 16 * 12, grid_and_nodes.end());
  int beyond = 0, total = 0;
  for (std::size_t k = 0; k < d.size(); ++k) {
    total++;
    beyond += d[k] > 4 * r.uncertainty_px[k];
  }
  EXPECT_LE(beyond, total / 20) << "errors beyond 4 predicted sigmas";
  EXPECT_NEAR(r.observed_pixel_sigma_px, expected_rms, 0.02 * expected_rms);
  // Without the rotation fit the camera frame's weak mode shows: still small.
  const auto naive = projection_difference_grid(s.truth, r.model, 16, 12);
  std::printf("without the rotation fit: worst %.3f px\n", *std::max_element(naive.begin(), naive.end()));
  EXPECT_NEAR(r.model.intrinsics[0], 1000.0, 2.0);
  // Seeded without a focal guess: from the homographies (a pinhole view of a
  // lens with 130 px of barrel distortion: within 30 %).
  EXPECT_EQ(r.focal_seed_method, "homographies");
  EXPECT_NEAR(r.focal_seed_px, 1000.0, 300.0);
  for (const auto& v : r.views) EXPECT_TRUE(v.used);
  // Board poses against the truth.
  for (std::size_t k = 0; k < s.poses.size(); ++k) {
    EXPECT_LT((r.views[k].cam_from_board.translation - s.poses[k].translation).norm(), 2.0) << k;
  }
}

nlohmann::json compare_with_mrcal(const Shared& s) {
  // Our solution, for mrcal's Python to evaluate the uncertainty on our problem.
  nlohmann::json sol{{"intrinsics", s.ours.model.intrinsics},
                     {"warp", {s.ours.calobject_warp_x_mm, s.ours.calobject_warp_y_mm}}};
  for (const auto& v : s.ours.views) sol["frames"].push_back(v.cam_from_board.to_rt());
  std::vector<double> weights;
  for (const auto& v : s.views)
    for (const auto& c : v.corners) weights.push_back(c.z());
  for (const auto& o : s.ours.outlier_corners)
    weights[(o.view * kGrid.height + o.row) * kGrid.width + o.col] = -1;
  sol["weights"] = weights;
  const fs::path sol_path = scratch() / "solution.json";
  std::ofstream(sol_path) << sol.dump();
  const std::string cmd = "/usr/bin/python3 " + std::string(CLEARFIT_SAMPLES_DIR) +
                          "/../tests/tools/mrcal_compare.py --ours " + s.ours_path.string() + " --mrcal " +
                          s.mrcal_path.string() + " --grid 17 13 --distance " +
                          std::to_string(s.ours.uncertainty_distance_mm) + " --sigma " +
                          std::to_string(s.ours.observed_pixel_sigma_px) + " --solution " + sol_path.string() +
                          " --solution-weight-scale " + std::to_string(s.ours.corner_weight_scale);
  std::string out = run(cmd);
  const auto brace = out.find('{');  // mrcal may print notes before the JSON
  return nlohmann::json::parse(out.substr(brace == std::string::npos ? 0 : brace));
}

TEST(Calibrate, MatchesMrcalCalibrateCameras) {
  const Shared& s = shared();
  const nlohmann::json j = compare_with_mrcal(s);
  // mrcal's Python reads our file and gets our intrinsics back exactly.
  EXPECT_EQ(j["ours"]["lensmodel"], "LENSMODEL_OPENCV8");
  EXPECT_EQ(j["ours"]["imagersize"], nlohmann::json({1280, 960}));
  for (std::size_t k = 0; k < s.ours.model.intrinsics.size(); ++k)
    EXPECT_EQ(j["ours"]["intrinsics"][k].get<double>(), s.ours.model.intrinsics[k]) << k;
  const double tool_rms = j["mrcal"]["rms_px"];
  std::printf("RMS: ours %.4f px (%d corners), mrcal-calibrate-cameras %.4f px (%d corners)\n", s.ours.rms_px,
              s.ours.corners_used, tool_rms, j["mrcal"]["inliers"].get<int>());
  EXPECT_NEAR(s.ours.rms_px, tool_rms, 0.03 * tool_rms);
  // Projection difference between the two models (mrcal.projection_diff)
  // against their combined uncertainty, over the cells both observed.
  const auto diff = j["diff_px"].get<std::vector<double>>();
  const auto unc_tool = j["uncertainty_px"].get<std::vector<double>>();
  ASSERT_EQ(diff.size(), s.ours.uncertainty_px.size());
  double worst = 0, worst_ratio = 0, sum_ratio = 0;
  for (std::size_t k = 0; k < diff.size(); ++k) {
    const double combined = std::hypot(s.ours.uncertainty_px[k], unc_tool[k]);
    worst = std::max(worst, diff[k]);
    worst_ratio = std::max(worst_ratio, diff[k] / combined);
    sum_ratio += diff[k] / combined;
  }
  std::printf("projection diff ours vs mrcal: worst %.3f px, worst/combined-sigma %.2f, mean %.2f\n", worst,
              worst_ratio, sum_ratio / diff.size());
  EXPECT_LT(worst, 0.6);
  EXPECT_LT(sum_ratio / diff.size(), 2.0);
  // Our uncertainty (finite-difference Jacobian of mrcal's residuals, our
  // propagation) against mrcal's Python projection_uncertainty on the same
  // problem at the same solution.
  // At every node of the grid, edge to edge: the image's corners (nodes (0, 0), (16, 0), (0, 12), (16, 12)),
  // where no corner was seen and the uncertainty is largest, included.
  const auto unc_py = j["uncertainty_ours_px"].get<std::vector<double>>();
  ASSERT_EQ(unc_py.size(), s.ours.uncertainty_px.size());
  double worst_rel = 0, corner_rel = 0, corner_max = 0;
  for (std::size_t k = 0; k < unc_py.size(); ++k)
    worst_rel = std::max(worst_rel, std::abs(s.ours.uncertainty_px[k] / unc_py[k] - 1));
  for (const std::size_t k : {0u, 16u, 12u * 17u, 12u * 17u + 16u}) {
    corner_rel = std::max(corner_rel, std::abs(s.ours.uncertainty_px[k] / unc_py[k] - 1));
    corner_max = std::max(corner_max, s.ours.uncertainty_px[k]);
  }
  const double largest = *std::max_element(s.ours.uncertainty_px.begin(), s.ours.uncertainty_px.end());
  std::printf(
      "uncertainty: ours vs mrcal's Python on our solution: worst relative difference %.2e, at the image corners %.2e; "
      "centre %.4f px (node %.4f), image corners up to %.4f px, largest %.4f px; mrcal's tool's own solve: centre node %.4f px\n",
      worst_rel, corner_rel, s.ours.uncertainty_center_px, s.ours.uncertainty_px[6 * 17 + 8], corner_max, largest, unc_tool[6 * 17 + 8]);
  // Measured: 1.1e-5 over the nodes, 6.9e-7 at the image corners (the finite-difference Jacobian's steps).
  EXPECT_LT(worst_rel, 1e-4);
  EXPECT_LT(corner_rel, 1e-5);
  EXPECT_EQ(corner_max, largest);  // the map peaks where the data did not reach
  EXPECT_NEAR(s.ours.uncertainty_px[6 * 17 + 8], s.ours.uncertainty_center_px, 1e-12);  // node (8, 6) is the centre
  // The tool's model against the truth, for the record (same metric as ours).
  const CameraModel tool = read_cameramodel(s.mrcal_path);
  const Stats e = error_vs_truth(s.truth, tool, s.ours);
  const Stats o = error_vs_truth(s.truth, s.ours.model, s.ours);
  std::printf(
      "vs truth: mrcal tool centre %.4f rms %.4f worst %.4f; ours centre %.4f rms %.4f worst %.4f px\n",
      e.centre, e.rms, e.worst, o.centre, o.rms, o.worst);
  EXPECT_LT(o.rms, 1.5 * e.rms + 0.02);
}

// A 112-degree lens (an equidistant fisheye, r = f theta, fitted by OPENCV8's
// rational model: large rational coefficients), sharp corners (0.05 px), and
// no corner beyond 85 % of the half diagonal: the image corners are
// extrapolated. mrcal's regularisation, sized for 1 px corners, outweighed
// such data and bent the model where the views thin out.
struct WideLensError {
  double whole_p95 = 0, whole_max = 0, observed_max = 0;
};
WideLensError wide_lens_error(const CameraModel& truth, const CameraModel& model,
                              const std::vector<BoardObservation>& views) {
  const int nx = 32, ny = 24;
  std::vector<int> observed(nx * ny, 0);
  for (const auto& v : views)
    for (const auto& c : v.corners)
      if (c.z() > 0)
        ++observed[std::clamp(static_cast<int>((c.y() + 0.5) / truth.height * ny), 0, ny - 1) * nx +
                   std::clamp(static_cast<int>((c.x() + 0.5) / truth.width * nx), 0, nx - 1)];
  std::vector<double> d = projection_difference_grid(truth, model, nx, ny, observed);
  WideLensError e;
  for (std::size_t k = 0; k < d.size(); ++k) {
    if (!std::isfinite(d[k])) d[k] = 1e9;
    if (observed[k]) e.observed_max = std::max(e.observed_max, d[k]);
  }
  std::sort(d.begin(), d.end());
  e.whole_p95 = d[static_cast<std::size_t>(0.95 * (d.size() - 1))];
  e.whole_max = d.back();
  return e;
}

TEST(Calibrate, WideLensExtrapolatesBeyondTheViews) {
  // bench/widelens_bench.cpp renders boards through the same lens.
  const CameraModel truth{"LENSMODEL_OPENCV8",
                          {655.0, 656.0, 641.3, 478.6, 0.6243, 0.05934, 0.0005, -0.0003, 0.000452, 0.9563, 0.1827, 0.005247},
                          1280, 960, {}, {}};
  SyntheticViewsOptions o;
  o.views = 30;
  o.noise_px = 0.05;
  o.seed = 5;
  o.min_distance_mm = 350;
  o.max_distance_mm = 900;
  o.min_inside_fraction = 0.6;
  std::printf("wide lens: synthetic views seed %u, sigma %.2f px\n", o.seed, o.noise_px);
  std::vector<BoardObservation> views = synthesize_views(truth, kGrid, o);
  const Eigen::Vector2d centre(0.5 * (truth.width - 1), 0.5 * (truth.height - 1));
  for (auto& v : views)
    for (auto& c : v.corners)
      if (c.z() > 0 && (c.head<2>() - centre).norm() > 0.85 * centre.norm()) c = {-1, -1, -1};
  CalibrationOptions opt;
  opt.compute_uncertainty = false;
  const CalibrationResult ours = calibrate_camera(views, kGrid, opt);
  opt.scale_regularization_to_noise = false;
  const CalibrationResult sized = calibrate_camera(views, kGrid, opt);
  // mrcal's tool on the same corners (required: CI installs it).
  const fs::path dir = scratch() / "wide";
  fs::create_directories(dir / "mrcal");
  write_corners_levels_vnl(views, dir / "corners.vnl");
  run_mrcal_tool(dir, "--corners-cache corners.vnl --lensmodel LENSMODEL_OPENCV8 --focal 650 --imagersize 1280 960 "
                     "--object-spacing 30 --object-width-n 10 --object-height-n 10 --outdir mrcal");
  const CameraModel tool = read_cameramodel(dir / "mrcal" / "camera-0.cameramodel");
  const WideLensError e = wide_lens_error(truth, ours.model, views), s = wide_lens_error(truth, sized.model, views),
                      t = wide_lens_error(truth, tool, views);
  std::printf("error vs truth (whole p95 / whole max / observed max, px): ours (weights x %.1f) %.3f / %.2f / %.3f; "
              "mrcal's sizing %.3f / %.2f / %.3f; mrcal-calibrate-cameras %.3f / %.2f / %.3f\n",
              ours.corner_weight_scale, e.whole_p95, e.whole_max, e.observed_max, s.whole_p95, s.whole_max,
              s.observed_max, t.whole_p95, t.whole_max, t.observed_max);
  EXPECT_GT(ours.corner_weight_scale, 10.0);  // 1 px over about 0.05 px
  EXPECT_DOUBLE_EQ(sized.corner_weight_scale, 1.0);
  EXPECT_LT(e.observed_max, 0.15);
  EXPECT_LT(e.whole_p95, 0.5 * t.whole_p95);
  EXPECT_LT(e.whole_max, t.whole_max);
  EXPECT_LT(e.whole_p95, 0.5 * s.whole_p95);
}

TEST(CalibrationOptions, DefaultsAreValidAndFieldsNamed) {
  EXPECT_NO_THROW(CalibrationOptions{}.validate());
  CalibrationOptions o;
  o.focal_px = -3;
  try {
    o.validate();
    ADD_FAILURE();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("focal_px = -3"), std::string::npos) << e.what();
  }
}

// --- lens models ------------------------------------------------------------

std::vector<BoardObservation> small_set(unsigned seed, int views = 20, double noise = 0.2) {
  SyntheticViewsOptions o;
  o.views = views;
  o.noise_px = noise;
  o.seed = seed;
  std::printf("synthetic views: seed %u, %d views, sigma %.2f px\n", seed, views, noise);
  return synthesize_views(true_lens(), kGrid, o);
}

TEST(Calibrate, Opencv12SeededFromOpencv8) {
  CalibrationOptions opt;
  opt.lensmodel = "LENSMODEL_OPENCV12";
  opt.compute_uncertainty = false;
  const auto r = calibrate_camera(small_set(11), kGrid, opt);
  EXPECT_EQ(r.lensmodel_chain, "LENSMODEL_PINHOLE -> LENSMODEL_OPENCV8 -> LENSMODEL_OPENCV12");
  EXPECT_EQ(r.model.intrinsics.size(), 16u);
  const auto d =
      projection_difference_grid(true_lens(), r.model, r.coverage_cells_x, r.coverage_cells_y, r.coverage);
  double worst = 0;
  for (std::size_t k = 0; k < d.size(); ++k)
    if (r.coverage[k]) worst = std::max(worst, d[k]);
  std::printf("OPENCV12: rms %.4f px, worst error vs truth %.3f px\n", r.rms_px, worst);
  EXPECT_LT(r.rms_px, 0.21);
  EXPECT_LT(worst, 0.6);
}

TEST(Calibrate, SplinedModelFitsOpencv8Lens) {
  CalibrationOptions opt;
  opt.lensmodel = "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=12_Ny=9_fov_x_deg=80";
  opt.compute_uncertainty = false;
  const auto r = calibrate_camera(small_set(12, 30), kGrid, opt);
  EXPECT_EQ(r.lensmodel_chain, "LENSMODEL_STEREOGRAPHIC -> " + opt.lensmodel);
  const auto d =
      projection_difference_grid(true_lens(), r.model, r.coverage_cells_x, r.coverage_cells_y, r.coverage);
  double worst = 0;
  for (std::size_t k = 0; k < d.size(); ++k)
    if (r.coverage[k]) worst = std::max(worst, d[k]);
  std::printf("splined: rms %.4f px, worst error vs truth over observed cells %.3f px\n", r.rms_px, worst);
  EXPECT_LT(r.rms_px, 0.22);
  EXPECT_LT(worst, 1.0);
}

// --- bad input ----------------------------------------------------------------

template <class F>
std::string input_error(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no InputError";
  return {};
}

TEST(CalibrateBadInput, TooFewViews) {
  const auto v = small_set(21, 2);
  EXPECT_NE(input_error([&] { calibrate_camera(v, kGrid); }).find("at least 3 are needed"),
            std::string::npos);
}

TEST(CalibrateBadInput, NoDetections) {
  auto v = small_set(22, 4);
  for (auto& view : v)
    for (auto& c : view.corners) c = {-1, -1, -1};
  const std::string e = input_error([&] { calibrate_camera(v, kGrid); });
  EXPECT_NE(e.find("only 0 views have board corners"), std::string::npos) << e;
}

TEST(CalibrateBadInput, MixedImageSizes) {
  auto v = small_set(23, 4);
  v[2].width = 640;
  v[2].height = 480;
  const std::string e = input_error([&] { calibrate_camera(v, kGrid); });
  EXPECT_NE(e.find("frame002.png"), std::string::npos) << e;
  EXPECT_NE(e.find("640 x 480 differs"), std::string::npos) << e;
}

TEST(CalibrateBadInput, BoardFileDisagreesWithPrintedBoard) {
  // The printed board has 12 x 8 corners; the board file says 8 x 12 (same count).
  const CalibrationGrid printed{12, 8, 25.0}, described{8, 12, 25.0};
  SyntheticViewsOptions o;
  o.views = 12;
  o.seed = 24;
  const auto v = synthesize_views(true_lens(), printed, o);
  const std::string e = input_error([&] { calibrate_camera(v, described); });
  EXPECT_NE(e.find("inconsistent with a 8 x 12 grid"), std::string::npos) << e;
  // The right description passes.
  CalibrationOptions opt;
  opt.compute_uncertainty = false;
  EXPECT_LT(calibrate_camera(v, printed, opt).rms_px, 0.35);
}

TEST(CalibrateBadInput, UnknownLensModel) {
  CalibrationOptions opt;
  opt.lensmodel = "LENSMODEL_FISHEYE9";
  const std::string e = input_error([&] { calibrate_camera(small_set(25, 4), kGrid, opt); });
  EXPECT_NE(e.find("unknown lens model"), std::string::npos) << e;
}

TEST(CalibrateWarnings, AllViewsAtOneDistanceAndEmptyCorners) {
  SyntheticViewsOptions o;
  o.views = 15;
  o.seed = 26;
  o.min_distance_mm = o.max_distance_mm = 1100;
  const auto v = synthesize_views(true_lens(), kGrid, o);
  CalibrationOptions opt;
  opt.compute_uncertainty = false;
  const auto r = calibrate_camera(v, kGrid, opt);
  const auto has = [&](const std::string& s) {
    return std::any_of(r.warnings.begin(), r.warnings.end(),
                       [&](auto& w) { return w.find(s) != std::string::npos; });
  };
  EXPECT_TRUE(has("about one distance")) << ::testing::PrintToString(r.warnings);
  // The shared 30-view set spans 400-1200 mm: no such warning there.
  const auto& w = shared().ours.warnings;
  EXPECT_FALSE(
      std::any_of(w.begin(), w.end(), [](auto& s) { return s.find("one distance") != std::string::npos; }));
}

TEST(CalibrateWarnings, UncoveredImageRegions) {
  // Boards only in the left half of the image.
  auto v = small_set(27, 20);
  for (auto& view : v)
    for (auto& c : view.corners)
      if (c.x() > 600) c = {-1, -1, -1};
  CalibrationOptions opt;
  opt.compute_uncertainty = false;
  const auto r = calibrate_camera(v, kGrid, opt);
  ASSERT_FALSE(r.warnings.empty());
  const bool named = std::any_of(r.warnings.begin(), r.warnings.end(), [](auto& s) {
    return s.find("regions of the image have no board corners") != std::string::npos &&
           s.find("top-right") != std::string::npos;
  });
  EXPECT_TRUE(named) << ::testing::PrintToString(r.warnings);
  EXPECT_EQ(r.coverage[r.coverage_cells_x - 1], 0);
}

// --- files ------------------------------------------------------------------------

TEST(CornersVnl, RoundTripAndMissing) {
  auto v = small_set(28, 3);
  v[1].corners.assign(v[1].corners.size(), Eigen::Vector3d(-1, -1, -1));  // no detection
  v[0].corners[5].z() = 0.5;                                              // level 1
  const fs::path p = scratch() / "roundtrip.vnl";
  write_corners_levels_vnl(v, p);
  const auto back = read_corners_vnl(p, kGrid, 1280, 960);
  ASSERT_EQ(back.size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(back[k].image, v[k].image);
    for (std::size_t c = 0; c < v[k].corners.size(); ++c) {
      if (v[k].corners[c].z() < 0)
        EXPECT_LT(back[k].corners[c].z(), 0);
      else
        EXPECT_EQ(back[k].corners[c], v[k].corners[c]) << k << " " << c;
    }
  }
  // A wrong grid names the file and line.
  const std::string e = input_error([&] { read_corners_vnl(p, {9, 10, 30}, 1280, 960); });
  EXPECT_NE(e.find("line 2"), std::string::npos) << e;
  EXPECT_NE(e.find("needs 90"), std::string::npos) << e;
}

// --- OpenCV calibration files --------------------------------------------------------

TEST(OpencvYaml, ProjectionsMatchCvProjectPoints) {
  std::mt19937 rng(31);
  std::printf("seed 31\n");
  std::uniform_real_distribution<double> u(-1, 1);
  const std::vector<std::vector<double>> coefficient_sets{
      {},
      {0, 0, 0, 0, 0},
      {-0.21, 0.05, 0.001, -0.0007},
      {-0.21, 0.05, 0.001, -0.0007, 0.012},
      {-0.3, 0.1, 0.001, -0.0005, -0.02, 0.02, 0.01, 0.003},
      {-0.3, 0.1, 0.001, -0.0005, -0.02, 0.02, 0.01, 0.003, 0.001, -0.0004, 0.0008, 0.0002}};
  const std::vector<std::string> expected{"LENSMODEL_PINHOLE", "LENSMODEL_PINHOLE", "LENSMODEL_OPENCV4",
                                          "LENSMODEL_OPENCV5", "LENSMODEL_OPENCV8", "LENSMODEL_OPENCV12"};
  for (std::size_t s = 0; s < coefficient_sets.size(); ++s) {
    const cv::Mat K = (cv::Mat_<double>(3, 3) << 1210.5, 0, 955.25, 0, 1208.0, 541.75, 0, 0, 1);
    const cv::Mat D = coefficient_sets[s].empty() ? cv::Mat() : cv::Mat(coefficient_sets[s]).clone();
    const fs::path p = scratch() / ("opencv" + std::to_string(s) + ".yaml");
    {
      cv::FileStorage fs(p.string(), cv::FileStorage::WRITE);
      fs << "image_width" << 1920 << "image_height" << 1080 << "camera_matrix" << K;
      if (!D.empty()) fs << "distortion_coefficients" << D;
    }
    const CameraModel m = camera_from_opencv_yaml(p);
    EXPECT_EQ(m.lensmodel, expected[s]);
    EXPECT_EQ(m.width, 1920);
    std::vector<cv::Point3d> pts;
    std::vector<Vec3> ours;
    for (int k = 0; k < 200; ++k) {
      const Vec3 x(u(rng) * 0.7, u(rng) * 0.4, 1.0);
      pts.emplace_back(x.x() * 3, x.y() * 3, 3.0);
      ours.push_back(x * 3);
    }
    std::vector<cv::Point2d> cvq;
    cv::projectPoints(pts, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, D, cvq);
    const auto q = m.project(ours);
    double worst = 0;
    for (std::size_t k = 0; k < q.size(); ++k)
      worst = std::max(worst, (q[k] - Vec2(cvq[k].x, cvq[k].y)).norm());
    EXPECT_LT(worst, 1e-6) << expected[s];
  }
}

TEST(OpencvYaml, BadFiles) {
  const fs::path p = scratch() / "bad.yaml";
  {
    cv::FileStorage fs(p.string(), cv::FileStorage::WRITE);
    fs << "image_width" << 640 << "image_height" << 480 << "camera_matrix"
       << (cv::Mat_<double>(3, 3) << 500, 2, 320, 0, 500, 240, 0, 0, 1);
  }
  EXPECT_NE(input_error([&] { camera_from_opencv_yaml(p); }).find("skew"), std::string::npos);
  {
    cv::FileStorage fs(p.string(), cv::FileStorage::WRITE);
    fs << "image_width" << 640 << "image_height" << 480 << "camera_matrix"
       << (cv::Mat_<double>(3, 3) << 500, 0, 320, 0, 500, 240, 0, 0, 1) << "distortion_coefficients"
       << cv::Mat(std::vector<double>(14, 0.01));
  }
  EXPECT_NE(input_error([&] { camera_from_opencv_yaml(p); }).find("14"), std::string::npos);
  {
    cv::FileStorage fs(p.string(), cv::FileStorage::WRITE);
    fs << "image_width" << 640;
  }
  EXPECT_NE(input_error([&] { camera_from_opencv_yaml(p); }).find("camera_matrix"), std::string::npos);
  std::ofstream(p) << "this: is: not: yaml: [";
  EXPECT_FALSE(input_error([&] { camera_from_opencv_yaml(p); }).empty());
}

}  // namespace
}  // namespace clearfit
