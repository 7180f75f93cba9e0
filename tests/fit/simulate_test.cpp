// Synthetic captures: the rendered blanching against the skin model's closed
// form, the truth files, the video round trip and the calibration presses.
// Seeds are fixed and printed.
#include <clearfit/error.hpp>
#include <clearfit/fit/contact_mechanics.hpp>
#include <clearfit/fit/pressure_field_fit.hpp>
#include <clearfit/fit/pressure_model.hpp>
#include <clearfit/fit/simulate.hpp>
#include <clearfit/fit/srgb.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <unistd.h>

#include "../support/slab_view.hpp"

namespace clearfit::sim {
namespace {
namespace fs = std::filesystem;

// The slab scene (tests/support/slab_view.hpp) and the pixel that sees a chart point.
struct Bench : test::SlabView {
  explicit Bench(double medium_ior = 1.0) : SlabView(medium_ior) {}
  // Pixel that sees chart uv (nearest valid pixel).
  std::pair<int, int> pixel_at(const Vec2& uv) const {
    double best = 1e9;
    std::pair<int, int> px{-1, -1};
    for (int y = 0; y < map.height; ++y)
      for (int x = 0; x < map.width; ++x) {
        const auto c = map.chart_uv[map.index(x, y)];
        if (!c.allFinite()) continue;
        const double d = (c.cast<double>() - uv).norm();
        if (d < best) best = d, px = {x, y};
      }
    return px;
  }
};

// Mean linear green over a (2r+1)² block, frames averaged.
double mean_linear_green(const std::vector<cv::Mat>& frames, int cx, int cy, int r) {
  const float* lin = srgb::to_linear_table8();
  double sum = 0;
  long n = 0;
  for (const cv::Mat& f : frames)
    for (int y = cy - r; y <= cy + r; ++y)
      for (int x = cx - r; x <= cx + r; ++x) sum += lin[f.at<cv::Vec3b>(y, x)[1]], ++n;
  return sum / n;
}

PressureFieldSpec wide_gaussian(const Chart& chart, double peak) {
  PressureFieldSpec spec;
  PressureSource s;
  s.name = "plateau";
  s.center_uv_mm = 0.5 * (chart.uv_min + chart.uv_max);
  s.peak_kpa = peak, s.sigma_mm = 4;
  spec.sources = {s};
  return spec;
}
}  // namespace

TEST(Simulate, TruthFieldHotspotMatchesTheGaussianClosedForm) {
  Bench b;
  PressureFieldSpec spec = wide_gaussian(b.chart, 12);
  spec.sources[0].sigma_mm = 1.5;
  const PressureTruth t = make_pressure_truth(b.part.mesh, b.part.contact, b.chart, spec);
  ASSERT_EQ(t.hotspots.size(), 1u);
  const Hotspot& h = t.hotspots[0];
  EXPECT_NEAR((h.centroid_uv_mm - *spec.sources[0].center_uv_mm).norm(), 0, 0.01);
  EXPECT_NEAR(h.peak_kpa, 12, 0.01);
  // Area where 12·exp(−r²/(2σ²)) ≥ 4.3: π·2σ²·ln(12/4.3).
  EXPECT_NEAR(h.area_above_4_3_mm2, std::numbers::pi * 2 * 2.25 * std::log(12 / 4.3), 0.15);
  EXPECT_NEAR(h.area_above_5_5_mm2, std::numbers::pi * 2 * 2.25 * std::log(12 / 5.5), 0.15);
  ASSERT_TRUE(h.centroid_part_mm);
  EXPECT_NEAR(h.centroid_part_mm->z(), 0, 1e-9);  // on the contact face z = 0
  // A part-frame centre below the surface lands on it.
  PressureSource s = spec.sources[0];
  s.center_uv_mm.reset();
  s.center_part_mm = Vec3(2, -1, -0.7);
  spec.sources = {s};
  const PressureTruth t2 = make_pressure_truth(b.part.mesh, b.part.contact, b.chart, spec);
  ASSERT_TRUE(t2.source_part_mm[0]);
  EXPECT_NEAR((*t2.source_part_mm[0] - Vec3(2, -1, 0)).norm(), 0, 1e-9);
  ASSERT_TRUE(t2.hotspots[0].centroid_part_mm);
  EXPECT_NEAR((*t2.hotspots[0].centroid_part_mm - Vec3(2, -1, 0)).norm(), 0, 0.02);
  s.center_part_mm = Vec3(2, -1, -9);
  spec.sources = {s};
  EXPECT_THROW(make_pressure_truth(b.part.mesh, b.part.contact, b.chart, spec), InputError);
}

TEST(Simulate, RenderedBlanchingMatchesTheSkinModel) {
  for (double medium : {1.0, 1.49}) {  // air (refraction) and index-matched
    Bench b(medium);
    const PressureFieldSpec spec = wide_gaussian(b.chart, 20);
    const PressureTruth t = make_pressure_truth(b.part.mesh, b.part.contact, b.chart, spec);
    SkinParameters skin;
    skin.pulse_amplitude = 0;
    const ChartField drive = skin_drive(skin, t.pressure);
    CameraSettings cam;
    cam.texture_mm = 0.04;
    const std::uint64_t seed = 11;
    std::printf("seed %llu, medium %.2f\n", static_cast<unsigned long long>(seed), medium);
    const CaptureRenderer r(b.map, drive, skin, cam, seed);
    std::printf("renderer setup %.0f ms\n", r.setup_ms());
    const auto [cx, cy] = b.pixel_at(*spec.sources[0].center_uv_mm);
    ASSERT_GE(cx, 10);
    std::vector<cv::Mat> base, press;
    for (int k = 0; k < 12; ++k) base.push_back(r.render(k / 60.0, 0, Vec2::Zero(), k));
    for (int k = 0; k < 12; ++k) press.push_back(r.render(1 + k / 60.0, 1, Vec2::Zero(), 100 + k));
    // 12 frames × 169 pixels of ~4 % shot noise each: σ(y) ≈ 0.0013.
    const double y = std::log(mean_linear_green(press, cx, cy, 6) / mean_linear_green(base, cx, cy, 6));
    const double drive_c = drive.sample(*spec.sources[0].center_uv_mm);
    const double expected = skin.absorption[1] * steady_blood_loss(skin, drive_c);
    EXPECT_NEAR(drive_c, 20 * 16 / (16 + 0.09), 0.05);  // a Gaussian blurred by a Gaussian
    EXPECT_NEAR(y, expected, 0.004) << "medium " << medium;
    // The noiseless green agrees with the closed form too (specular and fall-off are common factors).
    const double yl = std::log((r.linear_green(cx, cy, 0, 1) - 0) / r.linear_green(cx, cy, 0, 0));
    EXPECT_NEAR(yl, expected, 0.02 * expected);
    // Far from the source nothing changes.
    const auto [fx, fy] = b.pixel_at(b.chart.uv_min + Vec2(1.0, 1.0));
    EXPECT_NEAR(std::log(mean_linear_green(press, fx, fy, 3) / mean_linear_green(base, fx, fy, 3)), 0, 0.004);
  }
}

TEST(Simulate, IntegerMotionShiftsTheImage) {
  Bench b;
  const PressureTruth t = make_pressure_truth(b.part.mesh, b.part.contact, b.chart, wide_gaussian(b.chart, 20));
  SkinParameters skin;
  skin.ridge_amplitude = 0.08;  // strong texture so that a wrong shift shows
  CameraSettings cam;
  cam.texture_mm = 0.04;
  cam.read_noise_e = 0, cam.full_well_e = 1e9;  // noiseless
  const CaptureRenderer r(b.map, skin_drive(skin, t.pressure), skin, cam, 3);
  const cv::Mat a = r.render(0.5, 0.5, Vec2::Zero(), 1), s = r.render(0.5, 0.5, Vec2(2, -1), 1);
  double same = 0, other = 0;
  for (int y = 80; y < 160; ++y)
    for (int x = 100; x < 220; ++x) {
      same += std::abs(s.at<cv::Vec3b>(y, x)[1] - a.at<cv::Vec3b>(y + 1, x - 2)[1]);
      other += std::abs(s.at<cv::Vec3b>(y, x)[1] - a.at<cv::Vec3b>(y, x)[1]);
    }
  EXPECT_LE(same, 80 * 120 * 0.01);  // a code level here and there from the (tiny) noise
  EXPECT_GT(other, 80 * 120 * 0.5);
}

TEST(Simulate, VideoRoundTripKeepsFramesAndAHalfPercentSignal) {
  Bench b;
  const PressureTruth t = make_pressure_truth(b.part.mesh, b.part.contact, b.chart, wide_gaussian(b.chart, 40));
  SkinParameters skin;
  skin.beta = 0.005 / 0.06;  // full blanching: y = k_G·β = 0.005
  skin.pulse_amplitude = 0;
  CameraSettings cam;
  cam.texture_mm = 0.04;
  const CaptureRenderer r(b.map, skin_drive(skin, t.pressure), skin, cam, 5);
  Timeline tl;
  tl.fps = 15, tl.baseline_s = 1, tl.press_s = 1, tl.single_video = true;
  skin.tau_on_s = 1e-3;  // the press is complete from its first frame
  const fs::path dir = fs::temp_directory_path() / ("clearfit_sim_video_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const auto [cx, cy] = b.pixel_at(0.5 * (b.chart.uv_min + b.chart.uv_max));
  for (VideoFormat f : {VideoFormat::ffv1, VideoFormat::huffyuv}) {
    const CaptureSummary sum = render_captures(r, skin, tl, cam, f, dir, 9);
    ASSERT_EQ(sum.files.size(), 1u);
    cv::VideoCapture cap((dir / sum.files[0]).string(), cv::CAP_FFMPEG);
    ASSERT_TRUE(cap.isOpened()) << to_string(f);
    std::vector<cv::Mat> decoded;
    for (cv::Mat m; cap.read(m);) decoded.push_back(m.clone());
    ASSERT_EQ(static_cast<int>(decoded.size()), 30) << to_string(f);
    EXPECT_EQ(static_cast<int>(cap.get(cv::CAP_PROP_FRAME_COUNT)), 30);
    // Lossless: identical to a fresh render of the same frames.
    for (int k : {0, 22}) {
      const double tt = k / 15.0, h = k < 15 ? 0.0 : 1 - std::exp(-(tt - 1 + 1 / 15.0) / skin.tau_on_s);
      EXPECT_EQ(cv::norm(decoded[k], r.render(tt, h, Vec2::Zero(), k), cv::NORM_INF), 0) << to_string(f) << " frame " << k;
    }
    const std::vector<cv::Mat> base(decoded.begin(), decoded.begin() + 15), press(decoded.begin() + 15, decoded.end());
    const double y = std::log(mean_linear_green(press, cx, cy, 8) / mean_linear_green(base, cx, cy, 8));
    EXPECT_NEAR(y, 0.005, 0.0008) << to_string(f);
  }
  fs::remove_all(dir);
}

TEST(Simulate, SubPixelChartUvFromBilinearMatchesATwiceFinerMap) {
  // The renderer's sub-pixel samples (±1/4 px) take chart uv bilinearly from the forward map. On a
  // curved band in air (two refractions), compare with a map traced at twice the resolution, whose
  // pixel (2x + a, 2y + b) is the sample (x − 1/4 + a/2, y − 1/4 + b/2) (mrcal pixel centres).
  test::TracePart part(shapes::cylindrical_shell(30, 32, 50, 20, 80, 16));
  const Chart chart = compute_chart(part.mesh, part.contact);
  CameraModel cam;
  cam.lensmodel = "LENSMODEL_PINHOLE";
  cam.intrinsics = {500, 500, 159.5, 119.5};
  cam.width = 320, cam.height = 240;
  CameraModel cam2 = cam;
  cam2.intrinsics = {1000, 1000, 2 * 160.0 - 0.5, 2 * 120.0 - 0.5};
  cam2.width = 640, cam2.height = 480;
  Rigid3 cam_from_part;
  cam_from_part.rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();
  cam_from_part.translation = Vec3(0, 0, 95);
  TraceScene sc = part.scene();
  sc.chart = &chart;
  const RefractionMap m1 = compute_refraction_map(sc, cam, cam_from_part), m2 = compute_refraction_map(sc, cam2, cam_from_part);
  std::vector<double> err;
  for (int y = 1; y < 239; ++y)
    for (int x = 1; x < 319; ++x)
      for (int b = 0; b < 2; ++b)
        for (int a = 0; a < 2; ++a) {
          const double sx = x - 0.25 + 0.5 * a, sy = y - 0.25 + 0.5 * b;
          const int x0 = static_cast<int>(std::floor(sx)), y0 = static_cast<int>(std::floor(sy));
          Vec2 uv = Vec2::Zero();
          bool ok = true;
          for (int dy = 0; dy < 2; ++dy)
            for (int dx = 0; dx < 2; ++dx) {
              const auto c = m1.chart_uv[m1.index(x0 + dx, y0 + dy)];
              ok = ok && c.allFinite();
              uv += (dx ? sx - x0 : 1 - (sx - x0)) * (dy ? sy - y0 : 1 - (sy - y0)) * c.cast<double>();
            }
          const auto exact = m2.chart_uv[m2.index(2 * x + a, 2 * y + b)];
          if (ok && exact.allFinite()) err.push_back((uv - exact.cast<double>()).norm() * 1000);
        }
  ASSERT_GT(err.size(), 50000u);
  std::sort(err.begin(), err.end());
  const double p50 = err[err.size() / 2], p99 = err[err.size() * 99 / 100], mx = err.back();
  std::printf("bilinear sub-pixel chart uv vs 2x map over %zu samples (pixel ~%.0f um): median %.3f um, p99 %.3f um, max %.3f um\n",
              err.size(), 1000 * (m1.chart_uv[m1.index(161, 120)] - m1.chart_uv[m1.index(160, 120)]).norm(), p50, p99, mx);
  EXPECT_LT(p99, 1.0);  // far below the 0.3 mm ridges and the skin blur
}

TEST(Simulate, TruthFilesAreConsistent) {
  Bench b;
  const PressureFieldSpec spec = wide_gaussian(b.chart, 9);
  const PressureTruth t = make_pressure_truth(b.part.mesh, b.part.contact, b.chart, spec);
  const fs::path dir = fs::temp_directory_path() / ("clearfit_sim_truth_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  CaptureSummary cap;
  cap.files = {"baseline.mkv", "worn.mkv"};
  cap.baseline_frames = 240, cap.press_frames = 180;
  write_truth(dir, spec, t, SkinParameters{}, CameraSettings{}, Timeline{}, cap, VideoFormat::ffv1, {320, 240}, 1, {{"scene", "x.yaml"}});
  const cv::Mat p = read_npy_2d(dir / "truth_pressure.npy");
  ASSERT_EQ(p.cols, t.pressure.grid.width);
  ASSERT_EQ(p.rows, t.pressure.grid.height);
  int nan = 0;
  for (int j = 0; j < p.rows; ++j)
    for (int i = 0; i < p.cols; ++i) {
      const float v = p.at<float>(j, i), w = t.pressure.value[t.pressure.grid.index(i, j)];
      if (std::isnan(w)) {
        ++nan;
        EXPECT_TRUE(std::isnan(v));
      } else {
        EXPECT_EQ(v, w);
      }
    }
  EXPECT_LT(nan, p.rows * p.cols / 4);  // the slab's chart is a rectangle: NaN only on the grid's rim
  std::ifstream in(dir / "truth.json");
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["schema"], "clearfit.simulation-truth/1");
  EXPECT_EQ(j["chart_grid"]["width"], t.pressure.grid.width);
  EXPECT_NEAR(j["calibration"]["y_max"].get<double>(), 0.06 * 0.85, 1e-12);
  EXPECT_EQ(j["hotspots"].size(), 1u);
  EXPECT_EQ(j["video"]["phases"][1]["frames"], 180);
  EXPECT_EQ(fs::file_size(dir / "truth_vertex_pressure.npy"), 128 + 4 * b.part.mesh.vertices.size());
  fs::remove_all(dir);
}

TEST(Simulate, PressesFollowTheLogisticAndSneddonBlanchesLess) {
  SkinParameters skin;
  CameraSettings cam;
  PressOptions o;
  o.profile = PressOptions::Profile::uniform;
  o.trial_jitter = 0, o.offset_sd = 0;
  const std::uint64_t seed = 4;
  std::printf("seed %llu\n", static_cast<unsigned long long>(seed));
  const auto trials = simulate_presses(skin, cam, o, seed);
  ASSERT_EQ(trials.size(), 27u);
  const EquivalentCalibration c = equivalent_calibration(skin);
  for (const PressTrial& t : trials) {
    EXPECT_NEAR(t.signal, c.y_max * normalized_logistic(t.mean_pressure_kpa, c.p50_kpa, c.width_kpa), 5e-4) << t.trial;
    EXPECT_NEAR(t.force_n, t.mean_pressure_kpa * std::numbers::pi * 2.25 / 1000, 1e-12);
  }
  o.profile = PressOptions::Profile::sneddon;
  o.diameters_mm = {5};
  const auto sneddon = simulate_presses(skin, cam, o, seed);
  // Sneddon's centre carries p_mean/2, so a flat indenter blanches less than a uniform load of the
  // same mean pressure until both saturate (measured: 0.0119 vs 0.0218 at 7.5 kPa, equal within 0.5 % at 30 kPa).
  for (int l = 1; l <= 4; ++l)
    EXPECT_LT(sneddon[l].signal_noiseless, 0.9 * c.y_max * normalized_logistic(sneddon[l].mean_pressure_kpa, c.p50_kpa, c.width_kpa)) << l;
  EXPECT_NEAR(sneddon[8].signal_noiseless, c.y_max * normalized_logistic(30, c.p50_kpa, c.width_kpa), 0.01 * c.y_max);
  const fs::path csv = fs::temp_directory_path() / ("clearfit_presses_" + std::to_string(::getpid()) + ".csv");
  write_presses_csv(trials, csv);
  std::ifstream in(csv);
  std::string header, first;
  std::getline(in, header), std::getline(in, first);
  EXPECT_EQ(header, "trial,indenter_diameter_mm,force_n,mean_pressure_kpa,signal");
  EXPECT_EQ(first.substr(0, 4), "1,3,");
  fs::remove(csv);
}

TEST(Simulate, SneddonPressesCarryTheRadialProfileThePressesCommandMeasures) {
  SkinParameters skin;
  CameraSettings cam;
  PressOptions o;
  o.diameters_mm = {5};
  o.trial_jitter = 0, o.offset_sd = 0;
  const auto trials = simulate_presses(skin, cam, o, 9);
  ASSERT_EQ(trials.size(), 27u);
  const PressTrial& t = trials[4];  // 15 kPa mean
  // Rings of 0.2 mm from the axis to the rim + 1 mm, as `clearfit presses` writes them.
  ASSERT_EQ(t.ring_edges_mm.size(), 18u);
  EXPECT_DOUBLE_EQ(t.ring_edges_mm.front(), 0.0);
  EXPECT_NEAR(t.ring_edges_mm.back(), 3.4, 1e-9);
  ASSERT_EQ(t.ring_signal.size(), 17u);
  // Sneddon's rim carries more pressure than the centre (p_mean/2 there): the ring at the rim blanches
  // more than the axis; beyond the rim the blur fades it towards the unpressed skin.
  EXPECT_GT(t.ring_signal[11], 1.5 * t.ring_signal[0]);
  EXPECT_LT(t.ring_signal[16], 0.5 * t.ring_signal[11]);
  // The rings inside the disc, weighted by their area, average to the disc's signal (sensor noise only).
  double sum = 0, area = 0;
  for (std::size_t k = 0; k + 1 < t.ring_edges_mm.size() && t.ring_edges_mm[k + 1] <= 2.5 + 1e-9; ++k) {
    const double a = t.ring_edges_mm[k + 1] * t.ring_edges_mm[k + 1] - t.ring_edges_mm[k] * t.ring_edges_mm[k];
    sum += a * t.ring_signal[k], area += a;
  }
  EXPECT_NEAR(sum / area, t.signal_noiseless, 0.03 * t.signal_noiseless);
  // Written and read back as the profile columns calibrate-pressure fits.
  const fs::path csv = fs::temp_directory_path() / ("clearfit_profiles_" + std::to_string(::getpid()) + ".csv");
  write_presses_csv(trials, csv);
  const auto read = read_presses_csv(csv);
  fs::remove(csv);
  ASSERT_EQ(read.size(), trials.size());
  EXPECT_TRUE(presses_have_profiles(read));
  EXPECT_EQ(read[4].ring_signal.size(), 17u);
  EXPECT_NEAR(read[4].ring_signal[11], t.ring_signal[11], 1e-9);
  // The uniform profile has no field to resolve.
  o.profile = PressOptions::Profile::uniform;
  EXPECT_TRUE(simulate_presses(skin, cam, o, 9)[4].ring_signal.empty());
}

}  // namespace clearfit::sim
