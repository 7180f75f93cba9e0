#include "trial_summary.hpp"

#include <clearfit/fit/simulate.hpp>
#include <clearfit/npy.hpp>

#include <cmath>
#include <fstream>
#include <numbers>

namespace clearfit::study {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

json number_or_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

/// Mean of the defined texels within `radius` of `centre`, and the share of the disc's texels that are defined.
std::pair<double, double> disc_mean(const ChartField& f, const Vec2& centre, double radius) {
  double sum = 0;
  long long n = 0, all = 0;
  for (int j = 0; j < f.grid.height; ++j)
    for (int i = 0; i < f.grid.width; ++i) {
      if ((f.grid.uv(i, j) - centre).norm() > radius) continue;
      ++all;
      const float v = f.value[f.grid.index(i, j)];
      if (std::isnan(v)) continue;
      sum += v;
      ++n;
    }
  return {n > 0 ? sum / n : NAN, all > 0 ? double(n) / double(all) : 0.0};
}

/// Mean of a profile over |s| in [lo, hi].
double band_mean(const RadialProfile& p, double lo, double hi) {
  double sum = 0;
  int n = 0;
  for (std::size_t k = 0; k < p.position_mm.size(); ++k) {
    const double s = std::abs(p.position_mm[k]);
    if (s < lo || s > hi || std::isnan(p.value[k])) continue;
    sum += p.value[k];
    ++n;
  }
  return n > 0 ? sum / n : NAN;
}

json profile_json(const RadialProfile& p) {
  json values = json::array();
  for (double v : p.value) values.push_back(number_or_null(v));
  return {{"position_mm", p.position_mm}, {"signal", values}, {"segments", p.segments}};
}

/// The (x, y) in the part frame of the assessment's largest place (its area at the lowest threshold), if any.
std::optional<Vec2> strongest_hotspot(const json& report) {
  std::optional<Vec2> best;
  double best_area = -1;
  for (const json& h : report.at("hotspots")) {
    const json uv = h.value("centroid_mm", json());
    if (!uv.is_array() || uv.size() != 3 || !uv[0].is_number() || !uv[1].is_number()) continue;
    double area = 0;
    if (h.contains("area_mm2") && h["area_mm2"].is_number()) area = h["area_mm2"].get<double>();
    else if (h.contains("areas") && h["areas"].is_array() && !h["areas"].empty() && h["areas"][0].is_object())
      area = h["areas"][0].value("area_mm2", 0.0);
    if (area > best_area) best_area = area, best = Vec2(uv[0].get<double>(), uv[1].get<double>());
  }
  return best;
}

}  // namespace

/// The assessment's field as seen along the part's z axis (analysis.hpp, plane_field).
static ChartField in_part_plane(const fs::path& assessment, const ChartField& field) {
  const npy::Float32Array a = npy::read_float32(assessment / "chart_points.npy");
  if (a.shape.size() != 3 || a.shape[0] != std::size_t(field.grid.height) || a.shape[1] != std::size_t(field.grid.width) ||
      a.shape[2] != 3)
    throw std::runtime_error((assessment / "chart_points.npy").string() + " does not match the chart grid of report.json");
  std::vector<Vec3> points(field.grid.size());
  for (std::size_t k = 0; k < points.size(); ++k) points[k] = Vec3(a.values[3 * k], a.values[3 * k + 1], a.values[3 * k + 2]);
  return plane_field(field, points, field.grid.texel_mm);
}

ChartField read_assessment_field(const fs::path& assessment, const std::string& npy) {
  std::ifstream in(assessment / "report.json");
  if (!in) throw std::runtime_error((assessment / "report.json").string() + " is missing");
  const json report = json::parse(in);
  const json& chart = report.at("chart");
  ChartField f;
  f.grid.width = chart.at("width").get<int>();
  f.grid.height = chart.at("height").get<int>();
  f.grid.texel_mm = chart.at("texel_mm").get<double>();
  f.grid.uv_origin = Vec2(chart.at("uv_min_mm")[0].get<double>(), chart.at("uv_min_mm")[1].get<double>());
  const cv::Mat m = sim::read_npy_2d(assessment / npy);
  if (m.rows != f.grid.height || m.cols != f.grid.width)
    throw std::runtime_error((assessment / npy).string() + " does not match the chart grid of report.json");
  cv::Mat m32;
  m.convertTo(m32, CV_32F);
  f.value.assign(m32.ptr<float>(), m32.ptr<float>() + f.grid.size());
  return f;
}

json summarise_trial(const Manifest& m, const Trial& t, const fs::path& assessment) {
  std::ifstream in(assessment / "report.json");
  const json report = json::parse(in);
  const ChartField signal = in_part_plane(assessment, read_assessment_field(assessment, "signal.npy"));
  const Condition& c = m.condition(t.condition);
  json s{{"participant", t.participant}, {"condition", t.condition}, {"force_n", nullptr}, {"mean_pressure_kpa", nullptr},
         {"hotspots", report.at("hotspots").size()}, {"noise_sigma", report.at("signal").at("noise_sigma")},
         {"blanched_area_mm2", report.at("signal").at("blanched_area_mm2")}, {"peak_kpa", nullptr}, {"mean_kpa", nullptr}};
  if (!report.at("pressure").is_null()) {
    s["peak_kpa"] = report["pressure"].at("peak_kpa");
    s["mean_kpa"] = report["pressure"].at("mean_kpa");
  }
  if (t.force_n) s["force_n"] = *t.force_n;
  std::optional<Vec2> centre = c.bump ? c.bump->centre_mm : std::nullopt;
  s["centre"] = centre ? "given" : "hotspot";
  if (!centre) centre = strongest_hotspot(report);
  if (!centre) {
    s["centre"] = "signal";
    centre = find_profile_centre(signal);
  }
  if (!centre) return s;  // no blanching at all: no profile, no contact figures
  s["centre_mm"] = {centre->x(), centre->y()};
  const RadialProfile profile = radial_profile(signal, *centre, m.analysis.profile);
  s["profile"] = profile_json(profile);
  if (!c.bump) return s;
  const double a = c.bump->diameter_mm / 2;
  const auto [contact, seen] = disc_mean(signal, *centre, a);
  s["contact_signal"] = number_or_null(contact);
  s["contact_seen_fraction"] = seen;
  s["rim_to_centre"] = number_or_null(band_mean(profile, 0.75 * a, a) / band_mean(profile, 0, 0.35 * a));
  if (t.force_n) s["mean_pressure_kpa"] = 1000.0 * *t.force_n / (std::numbers::pi * a * a);
  if (!report.at("pressure").is_null())
    s["contact_pressure_kpa"] =
        number_or_null(disc_mean(in_part_plane(assessment, read_assessment_field(assessment, "pressure.npy")), *centre, a).first);
  return s;
}

}  // namespace clearfit::study
