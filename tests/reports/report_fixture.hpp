#pragma once
// A hand-made assessment output folder (docs/assessment-outputs.md) for the
// report and compare tests: a flat plate's heatmap.glb written by
// write_heatmap_glb from an analytic pressure field (two Gaussian bumps), PNGs
// drawn with OpenCV, and a report.json written by hand following the schema.
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/reports/colormap.hpp>
#include <clearfit/reports/heatmap_glb.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

namespace clearfit::report_test {

namespace fs = std::filesystem;
using json = nlohmann::json;

struct Bump {
  double x_mm, y_mm, peak_kpa, sigma_mm;
};

struct FixtureOptions {
  bool calibrated = true;              ///< false: signal-only report (no calibration.pressure)
  std::vector<Bump> bumps = {{-8, 4, 20, 3}, {10, -5, 9, 2.5}};
  double thresholds_kpa = 5.5;         ///< the upper threshold (the lower is 4.3); hotspots: bumps above 4.3
  int n = 24;                          ///< slab quads per edge (4 n² triangles on the big faces)
  std::string odd_text = "plain";      ///< put into warnings, file names and options
  double shift_x_mm = 0;               ///< moves the whole plate (compare: positions disagree)
  bool write_glb = true, write_pngs = true;
  double detection_kpa = 0;            ///< below it a vertex reads 0 kPa with no σ (below detection), as assess writes it
};

/// The pressure of the fixture's bumps at (x, y), kPa.
inline double fixture_pressure(const FixtureOptions& o, double x, double y) {
  double p = 0;
  for (const Bump& b : o.bumps) p += b.peak_kpa * std::exp(-((x - b.x_mm) * (x - b.x_mm) + (y - b.y_mm) * (y - b.y_mm)) / (2 * b.sigma_mm * b.sigma_mm));
  return p;
}
/// The blanching signal the fixture pairs with pressure p (a saturating curve).
inline double fixture_signal(double p) { return 0.05 * p / (p + 8.0); }

/// Writes the folder `dir` (created) and returns report.json's content.
inline json make_assessment_folder(const fs::path& dir, const FixtureOptions& o = {}) {
  fs::create_directories(dir);
  Mesh mesh = shapes::slab(40, 30, 3, o.n);
  for (Vec3& v : mesh.vertices) v.x() += o.shift_x_mm;
  ContactSelector sel;
  sel.group = "contact";
  const ContactSurface contact = select_contact(mesh, sel);
  const Chart chart = compute_chart(mesh, contact);
  const int nv = mesh.num_vertices();
  std::vector<float> pressure(nv, NAN), signal(nv, NAN);
  std::vector<char> seen(nv, 0);
  for (int v = 0; v < nv; ++v) {
    if (!chart.uv[v].allFinite()) continue;
    const Vec3& p = mesh.vertices[v];
    if (p.x() - o.shift_x_mm > 17) continue;  // a strip the camera does not see
    seen[v] = 1;
    pressure[v] = static_cast<float>(fixture_pressure(o, p.x() - o.shift_x_mm, p.y()));
    signal[v] = static_cast<float>(fixture_signal(pressure[v]));
    if (pressure[v] < o.detection_kpa) pressure[v] = 0.f;
  }
  ChartField texture;
  texture.grid = ChartGrid::covering(chart.uv_min, chart.uv_max, 0.5);
  texture.value.assign(texture.grid.size(), NAN);
  for (int j = 0; j < texture.grid.height; ++j)
    for (int i = 0; i < texture.grid.width; ++i) {
      const Vec2 uv = texture.grid.uv(i, j);
      const Vec3 p = chart.origin + uv.x() * chart.axis_u + uv.y() * chart.axis_v;
      if (p.x() - o.shift_x_mm <= 17) {
        double kpa = fixture_pressure(o, p.x() - o.shift_x_mm, p.y());
        if (kpa < o.detection_kpa) kpa = 0;
        texture.value[texture.grid.index(i, j)] = static_cast<float>(o.calibrated ? kpa : fixture_signal(kpa));
      }
    }

  json hotspots = json::array();
  std::vector<HeatmapMarker> markers;
  int id = 0;
  for (const Bump& b : o.bumps) {
    if (b.peak_kpa < 4.3) continue;
    ++id;
    // Area above a threshold t of a Gaussian bump: 2 pi s² ln(peak / t); mean over it (peak - t) / ln(peak / t).
    auto area = [&](double t) { return b.peak_kpa > t ? 2 * M_PI * b.sigma_mm * b.sigma_mm * std::log(b.peak_kpa / t) : 0.0; };
    auto mean = [&](double t) { return b.peak_kpa > t ? (b.peak_kpa - t) / std::log(b.peak_kpa / t) : NAN; };
    json levels = json::array();
    for (double t : {4.3, o.thresholds_kpa})
      levels.push_back({{o.calibrated ? "threshold_kpa" : "threshold_signal", o.calibrated ? t : fixture_signal(t)},
                        {"area_mm2", area(t)}, {"area_sigma_mm2", 0.1 * area(t)},
                        {o.calibrated ? "mean_kpa" : "mean_signal", o.calibrated ? mean(t) : fixture_signal(mean(t))}});
    json h = {{"id", id}, {"area_mm2", area(4.3)}, {"centroid_mm", {b.x_mm + o.shift_x_mm, b.y_mm, 0.0}},
              {"centroid_uv_mm", {b.x_mm, b.y_mm}}, {"faces", {0}}, {"saturated_texels", 0}, {"levels", levels},
              {"unseen_area_mm2", 0.0}, {"unseen_share", 0.0}};
    if (o.calibrated) {
      h["threshold_kpa"] = 4.3;
      h["peak_kpa"] = b.peak_kpa;
      h["peak_sigma_kpa"] = 0.05 * b.peak_kpa + 0.3;
      h["mean_kpa"] = mean(4.3);
      h["mean_sigma_kpa"] = 0.4;
      h["centre_of_pressure_sigma_mm"] = 0.01 * b.sigma_mm + 0.02;
      h["centroid_sigma_mm"] = 0.015 * b.sigma_mm + 0.01;
    } else {
      h["threshold_kpa"] = nullptr;
      h["peak_kpa"] = h["peak_sigma_kpa"] = h["mean_kpa"] = h["mean_sigma_kpa"] = nullptr;
      h["peak_signal"] = fixture_signal(b.peak_kpa);
      h["mean_signal"] = fixture_signal(0.6 * b.peak_kpa);
    }
    hotspots.push_back(h);
    markers.push_back({id, Vec3(b.x_mm + o.shift_x_mm, b.y_mm, 0), "hotspot " + std::to_string(id)});
  }

  if (o.write_glb) {
    HeatmapInput in;
    in.mesh = &mesh;
    in.chart = &chart;
    in.values = o.calibrated ? pressure : signal;
    in.seen = seen;
    std::vector<float> pressure_sigma(nv, NAN);  // a σ that varies over the part (as a real one does)
    if (o.calibrated)
      for (std::size_t v = 0; v < nv; ++v) pressure_sigma[v] = 0.05f * pressure[v] + 0.3f;
    if (o.calibrated)
      for (std::size_t v = 0; v < nv; ++v)
        if (pressure[v] == 0.f && o.detection_kpa > 0) pressure_sigma[v] = NAN;
    in.scalars = {{"_PRESSURE_KPA", o.calibrated ? pressure : std::vector<float>(nv, NAN)},
                  {"_PRESSURE_SIGMA_KPA", pressure_sigma}, {"_BLANCH", signal}};
    in.texture = &texture;
    in.quantity = o.calibrated ? "pressure_kpa" : "signal";
    in.unit = o.calibrated ? "kPa" : "";
    in.range_lo = 0;
    in.range_hi = o.calibrated ? 30 : 0.05;
    in.hotspots = markers;
    write_heatmap_glb(in, dir / "heatmap.glb");
  }
  if (o.write_pngs) {
    const Colormap& cm = Colormap::get("viridis");
    cv::Mat chart_img(texture.grid.height, texture.grid.width, CV_8UC3);
    for (int j = 0; j < texture.grid.height; ++j)
      for (int i = 0; i < texture.grid.width; ++i) {
        const Rgb8 c = cm.srgb8(normalise_to_range(texture.value[texture.grid.index(i, j)], 0, o.calibrated ? 30 : 0.05));
        chart_img.at<cv::Vec3b>(j, i) = {c.b, c.g, c.r};
      }
    for (const Bump& b : o.bumps)
      if (b.peak_kpa >= o.thresholds_kpa)
        cv::circle(chart_img, cv::Point(static_cast<int>((b.x_mm - texture.grid.uv_origin.x()) / 0.5), static_cast<int>((b.y_mm - texture.grid.uv_origin.y()) / 0.5)),
                   static_cast<int>(2 * b.sigma_mm), cv::Scalar(255, 255, 255), 1);
    cv::imwrite((dir / "chart_pressure.png").string(), chart_img);
    cv::imwrite((dir / "chart_signal.png").string(), chart_img);
    cv::Mat skin(120, 160, CV_8UC3);
    for (int r = 0; r < skin.rows; ++r)
      for (int c = 0; c < skin.cols; ++c) skin.at<cv::Vec3b>(r, c) = cv::Vec3b(120 + r / 4, 140 + c / 8, 200);
    cv::imwrite((dir / "skin_camera.png").string(), skin);
    cv::Mat undistorted;
    cv::resize(skin, undistorted, cv::Size(80, 60));
    cv::imwrite((dir / "skin_chart.png").string(), undistorted);
  }

  double peak = 0;
  for (float p : pressure)
    if (std::isfinite(p)) peak = std::max(peak, static_cast<double>(p));
  json calibration_pressure = nullptr;
  if (o.calibrated)
    calibration_pressure = {{"source", "calib/anna.json"}, {"person", "anna"}, {"model", "logistic"}, {"y_max", 0.05},
                            {"p50_kpa", 8.0}, {"width_kpa", 2.0}, {"noise_sigma", 0.001}, {"rmse_kpa", 1.7},
                            {"r2", 0.81}, {"linear_r2", 0.52}, {"reference_r2", 0.439}, {"range_kpa", {0, 30}}};
  const json report = {
      {"schema", "clearfit.report/1"},
      {"clearfit_version", "0.1.0"},
      {"created_utc", "2026-11-22T12:00:00Z"},
      {"run_time_s", 12.3},
      {"scene", "scene.yaml"},
      {"options", {{"texel_mm", 0.5}, {"note", o.odd_text}}},
      {"inputs", {{{"role", "mesh"}, {"path", "plate " + o.odd_text + ".obj"}, {"sha256", std::string(64, 'a')}},
                  {{"role", "worn"}, {"path", "worn.mp4"}, {"sha256", std::string(64, 'b')}}}},
      {"part", {{"mesh", "plate " + o.odd_text + ".obj"}, {"vertices", nv}, {"faces", mesh.num_faces()}, {"ior", 1.49},
                {"medium_ior", 1.0}, {"contact_faces", contact.faces.size()}, {"contact_area_mm2", contact.area_mm2},
                {"fast_path", "flat-slab"}}},
      {"chart", {{"texel_mm", 0.5}, {"width", texture.grid.width}, {"height", texture.grid.height},
                 {"uv_min_mm", {chart.uv_min.x(), chart.uv_min.y()}}, {"uv_max_mm", {chart.uv_max.x(), chart.uv_max.y()}},
                 {"method", "planar"}, {"area_ratio_min", 1.0}, {"area_ratio_max", 1.0}}},
      {"coverage", {{"contact_area_mm2", 1200.0}, {"seen_area_mm2", 1110.0}, {"seen_fraction", 0.925},
                    {"hidden_fraction", {{"total_internal_reflection", 0.05}, {"outside_view", 0.025}, {"other", 0.0}}}}},
      {"captures", {{"baseline", {{"source", "plain.mp4"}, {"frames_total", 120}, {"frames_used", {10, 99}}, {"fps", 60.0},
                                  {"motion_px_max", 0.2}, {"motion_compensated", true}, {"saturated_fraction", 0.0}}},
                    {"worn", {{"source", "worn.mp4"}, {"frames_total", 120}, {"frames_used", {20, 119}}, {"fps", 60.0},
                              {"motion_px_max", 0.8}, {"motion_compensated", true}, {"saturated_fraction", 0.001}}},
                    {"split", nullptr}}},
      {"signal", {{"feature", "log_green_ratio"}, {"reference", "unpressed skin around the part"}, {"noise_sigma", 0.0012},
                  {"blanched_area_mm2", 140.0}, {"plain_difference_mean", 0.0004}}},
      {"calibration", {{"camera", {{"rms_px", 0.31}, {"source", "camera.cameramodel"}}},
                       {"pose", {{"source", "cameramodel extrinsics"}, {"uncertainty_mm", 0.05}, {"uncertainty_deg", 0.1}}},
                       {"pressure", calibration_pressure}}},
      {"pressure", o.calibrated ? json{{"unit", "kPa"}, {"colormap", "viridis"}, {"range_kpa", {0, 30}}, {"peak_kpa", peak},
                                       {"mean_kpa", 3.1}, {"below_detection_fraction", 0.4}, {"saturated_fraction", 0.0}}
                                : json(nullptr)},
      {"thresholds_kpa", o.calibrated ? json{4.3, o.thresholds_kpa} : json(nullptr)},
      {"thresholds_signal", o.calibrated ? json::array() : json{fixture_signal(4.3), fixture_signal(o.thresholds_kpa)}},
      {"hotspots", hotspots},
      {"warnings", {"motion during the worn capture: 0.8 px, compensated", o.odd_text}},
      {"outputs", {{"heatmap_glb", "heatmap.glb"}, {"chart_pressure_png", "chart_pressure.png"},
                   {"chart_signal_png", "chart_signal.png"}, {"skin_camera_png", "skin_camera.png"},
                   {"skin_chart_png", "skin_chart.png"}, {"pressure_npy", "pressure.npy"}, {"signal_npy", "signal.npy"}}}};
  std::ofstream(dir / "report.json") << report.dump(2);
  return report;
}

}  // namespace clearfit::report_test
