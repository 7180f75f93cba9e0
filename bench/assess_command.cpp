// clearfit-bench assess: the assessment's throughput against a bare decode of
// the same captures, and its accuracy against a simulation's truth.
#include <clearfit/atomic_file.hpp>
#include <clearfit/cli/assess_setup.hpp>
#include <clearfit/cli/commands.hpp>
#include <clearfit/error.hpp>
#include <clearfit/fit/capture.hpp>
#include <clearfit/npy.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <limits>

namespace clearfit::cli {

namespace fs = std::filesystem;

namespace {

/// Seconds to decode every frame of a capture, nothing else (the same reader).
double bare_decode_s(const fs::path& source, int* frames) {
  const auto t = std::chrono::steady_clock::now();
  FrameReader reader(source);
  cv::Mat frame;
  int n = 0;
  while (reader.read(frame)) ++n;
  *frames = n;
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

/// 3D distance from the median texel of `a` to the nearest texel of `b` (mm).
double median_nearest_mm(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  if (a.empty() || b.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::vector<double> d;
  for (const Vec3& p : a) {
    double best = INFINITY;
    for (const Vec3& q : b) best = std::min(best, (p - q).squaredNorm());
    d.push_back(std::sqrt(best));
  }
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

/// The crest of a field near `centre`: contact texels within 3 mm whose value
/// is at least 95 % of the largest there (a punch's rim ring, a Gaussian's top).
std::vector<Vec3> crest(const Assessment& a, const std::vector<float>& value, const Vec3& centre) {
  double top = -INFINITY;
  std::vector<std::size_t> near;
  for (std::size_t k = 0; k < value.size(); ++k)
    if (a.raster.face[k] >= 0 && std::isfinite(value[k]) && (a.raster.point[k] - centre).norm() < 3.0)
      near.push_back(k), top = std::max(top, static_cast<double>(value[k]));
  std::vector<Vec3> out;
  for (std::size_t k : near)
    if (value[k] >= 0.95 * top) out.push_back(a.raster.point[k]);
  return out;
}

/// Accuracy of an assessment against a simulation's truth (truth.json and
/// truth_pressure.npy written by clearfit simulate). Texels the camera does not
/// see are neither misses nor zeros: they are left out of the RMSE, the
/// sensitivity and the false alarms, and the share of the truth's pressed area
/// they hold is reported beside.
nlohmann::json accuracy_against_truth(const Assessment& a, const fs::path& truth_dir, double range_kpa) {
  std::ifstream in(truth_dir / "truth.json");
  if (!in) throw InputError((truth_dir / "truth.json").string(), "", "not found", "give --truth the folder clearfit simulate wrote");
  const nlohmann::json t = nlohmann::json::parse(in);
  const npy::Float32Array tp = npy::read_float32(truth_dir / "truth_pressure.npy");
  const auto& grid = t.at("chart_grid");
  ChartField truth;
  truth.grid.width = grid.at("width");
  truth.grid.height = grid.at("height");
  truth.grid.texel_mm = grid.at("texel_mm");
  truth.grid.uv_origin = Vec2(grid.at("uv_origin_mm")[0], grid.at("uv_origin_mm")[1]);
  truth.value = tp.values;
  if (tp.values.size() != truth.grid.size())
    throw InputError((truth_dir / "truth_pressure.npy").string(), "shape", "does not match truth.json's chart_grid");
  const ChartGrid& g = a.signal.y.grid;
  std::vector<float> truth_here(g.size(), std::numeric_limits<float>::quiet_NaN());
  double se = 0, pressed_mm2 = 0, pressed_unseen_mm2 = 0;
  long long n = 0, pos = 0, tp_n = 0, neg = 0, fp = 0;
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const auto k = g.index(i, j);
      if (a.raster.face[k] < 0) continue;
      const float tv = truth.sample(g.uv(i, j));
      truth_here[k] = tv;
      if (!std::isfinite(tv)) continue;
      const bool seen = std::isfinite(a.signal.y.value[k]);
      if (tv >= 5.5f) pressed_mm2 += a.raster.area_mm2[k], pressed_unseen_mm2 += seen ? 0.0 : a.raster.area_mm2[k];
      float est = a.calibrated ? a.pressure.value[k] : 0.f;
      if (a.calibrated && a.pressure_status[k] == static_cast<std::uint8_t>(PressureStatus::below_detection)) est = 0.f;
      if (!seen || !std::isfinite(est)) continue;
      se += (est - tv) * (est - tv);
      ++n;
      const bool detected = a.calibrated ? est >= 5.5f : false;
      if (tv >= 5.5f) ++pos, tp_n += detected;
      if (tv < 4.3f) ++neg, fp += detected;
    }
  nlohmann::json hotspots = nlohmann::json::array();
  for (const auto& th : t.at("hotspots")) {
    if (th.at("centroid_part_mm").is_null()) continue;
    const Vec3 c(th["centroid_part_mm"][0], th["centroid_part_mm"][1], th["centroid_part_mm"][2]);
    const Hotspot* best = nullptr;
    for (const Hotspot& h : a.hotspots)
      if (h.centre_of_pressure_mm.allFinite() && (!best || (h.centre_of_pressure_mm - c).norm() < (best->centre_of_pressure_mm - c).norm()))
        best = &h;
    nlohmann::json area55 = nullptr;
    if (best && a.calibrated)
      for (const HotspotLevel& l : best->levels)
        if (l.threshold == 5.5) area55 = l.area_mm2;
    const double crest_mm = a.calibrated ? median_nearest_mm(crest(a, a.pressure.value, c), crest(a, truth_here, c)) : NAN;
    hotspots.push_back({{"truth_centroid_mm", {c.x(), c.y(), c.z()}},
                        {"truth_peak_kpa", th.value("peak_kpa", 0.0)},
                        {"truth_area_5_5_mm2", th.value("area_ge_5_5_kpa_mm2", 0.0)},
                        {"found", best != nullptr},
                        {"centroid_error_mm", best ? nlohmann::json((best->centre_of_pressure_mm - c).norm()) : nlohmann::json(nullptr)},
                        {"peak_kpa", best && a.calibrated ? nlohmann::json(best->peak) : nlohmann::json(nullptr)},
                        {"area_5_5_mm2", area55},
                        {"unseen_beside_mm2", best ? nlohmann::json(best->unseen_area_mm2) : nlohmann::json(nullptr)},
                        {"crest_error_mm", std::isfinite(crest_mm) ? nlohmann::json(crest_mm) : nlohmann::json(nullptr)}});
  }
  const double rmse = n ? std::sqrt(se / n) : 0;
  return {{"texels_compared", n},
          {"rmse_kpa", a.calibrated ? nlohmann::json(rmse) : nlohmann::json(nullptr)},
          {"rmse_percent_of_range", a.calibrated ? nlohmann::json(100 * rmse / range_kpa) : nlohmann::json(nullptr)},
          {"sensitivity_5_5", pos && a.calibrated ? nlohmann::json(static_cast<double>(tp_n) / pos) : nlohmann::json(nullptr)},
          {"false_alarm_rate_5_5", neg && a.calibrated ? nlohmann::json(static_cast<double>(fp) / neg) : nlohmann::json(nullptr)},
          {"truth_pressed_area_mm2", pressed_mm2},
          {"pressed_unseen_fraction", pressed_mm2 > 0 ? pressed_unseen_mm2 / pressed_mm2 : 0.0},
          {"hotspots", hotspots}};
}

}  // namespace

Run add_bench_assess(CLI::App& app) {
  auto o = std::make_shared<AssessOpts>();
  auto truth = std::make_shared<std::string>();
  auto json_out = std::make_shared<std::string>();
  CLI::App* sub = app.add_subcommand("assess", "The assessment's throughput against a bare decode of the same captures, "
                                                  "and its accuracy against a simulation's truth");
  sub->add_option("scene", o->scene_file, "Scene file (YAML) with captures")->required();
  sub->add_option("--truth", *truth, "Folder with truth.json and truth_pressure.npy (clearfit simulate); default: the captures' folder if it has them");
  sub->add_option("--json", *json_out, "Also write the figures as JSON");
  add_assess_options(*sub, *o);
  return [o, truth, json_out]() {
    o->quiet = true;
    const auto p = prepare(*o);
    // Bare decode of the same captures, then the assessment (map from the cache).
    int frames = 0;
    double decode_s = 0;
    for (const auto& src : {p->sources.baseline, p->sources.worn, p->sources.both})
      if (!src.empty()) {
        int n = 0;
        decode_s += bare_decode_s(src, &n);
        frames += n;
      }
    const auto t = std::chrono::steady_clock::now();
    const Assessment a = assess_captures(p->view(), p->sources, p->calibration, p->options);
    const double assess_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
    const CameraModel& cam = p->part->camera;
    nlohmann::json r = {{"schema", "clearfit.bench-assess/1"},
                        {"image", {cam.width, cam.height}},
                        {"frames", frames},
                        {"bare_decode_fps", frames / decode_s},
                        {"assessment_fps", frames / assess_s},
                        {"ratio_to_decode", decode_s / assess_s},
                        {"per_frame_work_fps", a.work_ms > 0 ? frames / (a.work_ms / 1000) : 0.0},
                        {"per_frame_work_ms", frames ? a.work_ms / frames : 0.0},
                        {"assessment_s", assess_s}};
    fs::path truth_dir = *truth;
    if (truth_dir.empty()) {
      const fs::path first = !p->sources.both.empty() ? p->sources.both : p->sources.baseline;
      if (fs::exists(first.parent_path() / "truth.json")) truth_dir = first.parent_path();
    }
    const double range = p->calibration ? std::max(p->calibration->p_max_kpa, 1.0) : 30.0;
    if (!truth_dir.empty()) r["accuracy"] = accuracy_against_truth(a, truth_dir, range);
    std::cout << "clearfit-bench assess: " << fs::path(o->scene_file).filename().string() << " (" << cam.width << "x" << cam.height << ", "
              << frames << " frames)\n";
    std::cout << "  bare decode        " << fixed(frames / decode_s, 1) << " frames/s\n";
    std::cout << "  whole assessment   " << fixed(frames / assess_s, 1) << " frames/s = " << fixed(100 * decode_s / assess_s, 0)
              << " % of the bare decode rate (target >= 80 %)\n";
    std::cout << "  per-frame work     " << fixed(r["per_frame_work_ms"].get<double>(), 2) << " ms/frame = "
              << fixed(r["per_frame_work_fps"].get<double>(), 0) << " frames/s with decode excluded (target >= 240)\n";
    if (r.contains("accuracy")) {
      const auto& acc = r["accuracy"];
      if (!acc["rmse_kpa"].is_null())
        std::cout << "  pressure RMSE      " << fixed(acc["rmse_kpa"].get<double>(), 2) << " kPa = " << fixed(acc["rmse_percent_of_range"].get<double>(), 1)
                  << " % of the calibrated range " << fixed(range, 1) << " kPa (target <= 10 %)\n";
      if (!acc["sensitivity_5_5"].is_null())
        std::cout << "  >= 5.5 kPa         sensitivity " << fixed(100 * acc["sensitivity_5_5"].get<double>(), 1) << " % (target >= 90 %), false alarms "
                  << fixed(100 * acc["false_alarm_rate_5_5"].get<double>(), 2) << " % of texels below 4.3 kPa\n";
      std::cout << "  unseen             " << fixed(100 * acc["pressed_unseen_fraction"].get<double>(), 1) << " % of the truth's "
                << fixed(acc["truth_pressed_area_mm2"].get<double>(), 2) << " mm² >= 5.5 kPa is not seen (not scored)\n";
      for (const auto& h : acc["hotspots"])
        std::cout << "  hotspot at (" << fixed(h["truth_centroid_mm"][0].get<double>(), 2) << ", " << fixed(h["truth_centroid_mm"][1].get<double>(), 2)
                  << ", " << fixed(h["truth_centroid_mm"][2].get<double>(), 2) << ") mm: "
                  << (h["found"].get<bool>() ? "centroid error " + fixed(h["centroid_error_mm"].get<double>(), 3) + " mm (target <= 0.3)" : std::string("not found"))
                  << (h["peak_kpa"].is_null() ? "" : ", peak " + fixed(h["peak_kpa"].get<double>()) + " kPa (truth " + fixed(h["truth_peak_kpa"].get<double>()) + ")")
                  << (h["area_5_5_mm2"].is_null() ? "" : ", area >= 5.5 kPa " + fixed(h["area_5_5_mm2"].get<double>(), 2) + " mm² (truth " + fixed(h["truth_area_5_5_mm2"].get<double>(), 2) + ")")
                  << (h["crest_error_mm"].is_null() ? "" : ", crest " + fixed(h["crest_error_mm"].get<double>(), 3) + " mm from the truth's")
                  << (h["unseen_beside_mm2"].is_null() || h["unseen_beside_mm2"].get<double>() == 0 ? ""
                                                        : ", " + fixed(h["unseen_beside_mm2"].get<double>(), 2) + " mm² unseen beside it")
                  << "\n";
    }
    if (!json_out->empty()) write_file_atomically(*json_out, r.dump(2) + "\n");
    return 0;
  };
}

static const Registration registered{"assess", 20, add_bench_assess};

}  // namespace clearfit::cli
