#include <algorithm>
#include <chrono>
#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>
#include <clearfit/npy.hpp>
#include <clearfit/reports/assessment_report.hpp>
#include <clearfit/reports/assessment_tables.hpp>
#include <clearfit/reports/chart_images.hpp>
#include <clearfit/reports/heatmap_glb.hpp>
#include <clearfit/reports/timeline_report.hpp>
#include <cmath>
#include <ctime>
#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

namespace clearfit {
namespace {

using json = nlohmann::json;

json num(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }
json vec(const Vec3& v) { return v.allFinite() ? json{v.x(), v.y(), v.z()} : json(nullptr); }
json vec(const Vec2& v) { return v.allFinite() ? json{v.x(), v.y()} : json(nullptr); }

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buf;
}

json phase_json(const PhaseReport& p) {
  return {{"source", p.source},
          {"frames_total", p.frames_total},
          {"frames_used", {p.window.first, p.window.first + p.window.count - 1}},
          {"fps", p.fps > 0 ? num(p.fps) : json(nullptr)},  // null: no frame rate (a folder of images)
          {"motion_px_max", num(p.motion_px_max)},
          {"jitter_px_rms", num(p.jitter_px_rms)},
          {"rotation_deg_max", num(p.rotation_deg_max)},
          {"rotation_scale_px_max", num(p.rotation_scale_px_max)},
          {"motion_compensated", p.motion_compensated},
          {"saturated_fraction", num(p.saturated_fraction)},
          {"mean_green_code", num(p.mean_code)},
          {"chunk_gain_range", {num(p.gain_min), num(p.gain_max)}},
          {"chunk_gain_sigma", num(p.gain_sigma)},
          {"codec", p.codec},
          {"lossy", p.lossy},
          {"pixel_format", p.pixel_format},
          {"colour_matrix", p.colour_matrix},
          {"limited_range", p.limited_range},
          {"rotation_deg", p.rotation_deg},
          {"bit_depth", p.bit_depth}};
}

json glare_json(const GlareMask& g, const Coverage& cov) {
  if (g.empty()) return nullptr;
  return {{"regions", g.regions},
          {"masked_area_mm2", num(cov.glare_masked_mm2)},
          {"fraction_of_seen_pixels", num(g.fraction)},
          {"fraction_baseline", num(g.fraction_baseline)},
          {"fraction_worn", num(g.fraction_worn)},
          {"skin_blue_over_green", num(g.blue_over_green)},
          {"blanching_blue_ratio", num(g.blanching_ratio)},
          {"blanching_blue_ratio_measured", g.ratio_measured},
          {"change_sigma", num(g.change_sigma)},
          {"static_sigma", num(g.static_sigma)}};
}

json phase_move_json(const PhaseMoveReport& m) {
  auto vec = [](const Vec2& v) { return json{num(v.x()), num(v.y())}; };
  return {{"measured", m.measured},
          {"applied", m.applied},
          {"move_px", m.measured ? vec(m.move_px) : json(nullptr)},
          {"sigma_px", m.measured ? vec(m.sigma_px) : json(nullptr)},
          {"worn_outline_px", m.measured ? vec(m.worn_px) : json(nullptr)},
          {"baseline_outline_px", m.baseline_px ? vec(*m.baseline_px) : json(nullptr)},
          {"outline_contrast", num(m.contrast)},
          {"problem", m.problem.empty() ? json(nullptr) : json(m.problem)},
          {"meaning", "the worn capture's first frame against the pose, from the contact surface's outline in its average "
                      "(the skin's texture cannot tell a camera move from a slide); the worn capture is read displaced by it"}};
}

json baseline_geometry_json(const BaselineGeometryReport& b) {
  json j = {{"part", to_string(b.part)},
            {"gap_mm", num(b.gap_mm)},
            {"gap_sigma_mm", num(b.gap_sigma_mm)},
            {"gap_source", b.part == BaselinePart::touching ? "none" : b.estimate ? (b.gap_estimated ? "estimated" : "unsure") : "given"},
            {"pixels_seeing_skin", b.pixels_seeing_skin}};
  if (b.gap_estimated && b.signal_sigma_max > 0)  // carried (GapSearchOptions::sigma_in_signal)
    j["signal_sigma_from_gap"] = {{"median", num(b.signal_sigma_median)},
                                  {"max", num(b.signal_sigma_max)},
                                  {"unseen_mm2", num(b.unseen_off_gap_mm2)},
                                  {"meaning", "1-sigma of the blanching signal per texel from the gap's sigma (the signal read at the gap "
                                              "+- sigma); in each texel's sigma and detection gate; unseen_mm2: seen at the gap but at neither "
                                              "gap +- sigma, left unseen"}};
  if (b.part != BaselinePart::touching)
    j["phase_shift_px"] = b.phase_shift_measured ? json{{"value", {num(b.phase_shift_px.x()), num(b.phase_shift_px.y())}},
                                                        {"sigma", {num(b.phase_shift_sigma_px.x()), num(b.phase_shift_sigma_px.y())}},
                                                        {"meaning", "how far the skin texture moved in the image between the phases' first "
                                                                    "frames (camera or skin), measured with the gap; the phase "
                                                                    "registration follows it"}}
                                                  : json(nullptr);
  if (b.part != BaselinePart::touching) {
    const VignettingEstimate& v = b.vignetting;
    j["vignetting"] = {{"model", "V = 1 + v r^2 (r^2: squared distance from the image centre over the half-diagonal's)"},
                       {"estimated", v.estimated},
                       {"v_at_corner", num(v.v)},
                       {"v_sigma", num(v.sigma)},
                       {"parallax_r2_spread", num(v.spread)},
                       {"pixels", v.samples},
                       {"inlier_fraction", num(v.inlier_fraction)},
                       {"problem", v.problem.empty() ? json(nullptr) : json(v.problem)}};
  }
  if (b.estimate) {
    const GapEstimate& e = *b.estimate;
    json curve = json::array();
    for (const auto& [g, c] : e.curve) curve.push_back({num(g), num(c)});
    j["estimate"] = {{"texture_match", num(e.match)},
                     {"shift_mm_per_mm", num(e.shift_mm_per_mm)},
                     {"pixels", e.pixels},
                     {"pressed_pixels_left_out", e.pressed_pixels},
                     {"problem", e.problem.empty() ? json(nullptr) : json(e.problem)},
                     {"curve_gap_mm_cost", curve}};
  }
  return j;
}

json phase_registration_json(const PhaseRegistration& r) {
  if (!r.applied) return nullptr;
  return {{"method", "dense flow (DIS) on high-passed ln R - ratio ln G on the chart, texture-weighted Gaussian regularisation"},
          {"displacement_npy", "displacement.npy"},
          {"magnitude_mm", {{"median", num(r.median_mm)}, {"p95", num(r.p95_mm)}, {"max", num(r.max_mm)}}},
          {"texture_match_before", num(r.match_before)},
          {"texture_match_after", num(r.match_after)},
          {"weak_texture_fraction", num(r.weak_texture_fraction)},
          {"texels", r.texels},
          {"unsure", !r.warnings.empty()},
          {"time_ms", num(r.ms)}};
}

/// Colour range of the signal: 0 to its 99th percentile over the seen texels (at least 5 σ).
std::pair<double, double> signal_range(const BlanchingSignal& signal) {
  std::vector<float> v;
  for (float y : signal.y.value)
    if (std::isfinite(y)) v.push_back(y);
  double hi = 5 * std::max(signal.noise_sigma, 1e-4);
  if (!v.empty()) {
    const auto k = v.begin() + static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(v.size() - 1));
    std::nth_element(v.begin(), k, v.end());
    hi = std::max(hi, static_cast<double>(*k));
  }
  return {0.0, hi};
}

/// Colour range of the pressure heatmaps: 0 to the top of the calibration's range.
std::pair<double, double> pressure_range(const AssessmentContext& c) {
  return {0.0, c.calibration ? std::max(c.calibration->p_max_kpa, 1.0) : c.pressure_range_hi_kpa};
}

void write_field_npy(const ChartField& f, const std::filesystem::path& path) {
  const ChartGrid& g = f.grid;
  npy::write_float32(path, {static_cast<std::size_t>(g.height), static_cast<std::size_t>(g.width)},
                     [&](std::size_t row, float* out) { std::copy_n(f.value.begin() + static_cast<std::ptrdiff_t>(row * g.width), g.width, out); });
}

void write_png(const cv::Mat& image, const std::filesystem::path& path) {
  std::vector<unsigned char> bytes;
  if (image.empty() || !cv::imencode(".png", image, bytes))
    throw std::runtime_error("cannot encode " + path.filename().string() + " as PNG");
  write_file_atomically(path, std::string(bytes.begin(), bytes.end()));
}

/// The largest value of a per-texel field over the texels with a signal (0 when none).
double largest_where_seen(const Assessment& a, const ChartField& f) {
  double worst = 0;
  for (std::size_t k = 0; k < f.value.size(); ++k)
    if (std::isfinite(a.signal.y.value[k]) && std::isfinite(f.value[k])) worst = std::max(worst, static_cast<double>(f.value[k]));
  return worst;
}

/// The pose and how its uncertainty entered the σ: the largest skin position σ over the seen texels (mm, per
/// axis across the line of sight) and the largest rotation σ; null and "unknown" without a pose covariance.
json pose_json(const Assessment& a, const AssessmentScene& scene, const AssessmentContext& c) {
  json j = {{"source", c.pose_source}, {"uncertainty_mm", nullptr}, {"uncertainty_deg", nullptr}};
  if (!scene.pose_covariance || a.position_sigma_mm.value.empty()) {
    j["position_uncertainty"] = "unknown: the pose file carries no covariance (write it with `clearfit pose --out`), so the σ "
                                "has no term for where on the skin each texel lies";
    return j;
  }
  const auto& C = *scene.pose_covariance;
  j["uncertainty_mm"] = largest_where_seen(a, a.position_sigma_mm);
  j["uncertainty_deg"] = std::sqrt(std::max({C(0, 0), C(1, 1), C(2, 2), 0.0})) * 180 / M_PI;
  j["position_uncertainty"] = "from the pose file's covariance: in the σ of every texel as |∇signal| × the skin position's σ";
  return j;
}

/// The camera model's projection uncertainty and how it entered the σ: the largest σ_q (px) of the model,
/// the distance it was evaluated at, and the largest skin position σ it gave over the seen texels (mm per
/// axis); nulls and "unknown" when the model carries none.
json intrinsics_json(const Assessment& a, const AssessmentScene& scene) {
  json j = {{"largest_px", nullptr}, {"distance_mm", nullptr}, {"uncertainty_mm", nullptr}};
  if (!scene.projection_uncertainty || a.intrinsics_sigma_mm.value.empty()) {
    j["position_uncertainty"] = "unknown: the camera model carries no projection uncertainty (`clearfit calibrate` writes it), so the "
                                "sigma has no term for the intrinsics (0 used)";
    return j;
  }
  j["largest_px"] = scene.projection_uncertainty->largest();
  j["distance_mm"] = scene.projection_uncertainty->distance_mm;
  j["uncertainty_mm"] = largest_where_seen(a, a.intrinsics_sigma_mm);
  const ProjectionSigmaOnContact& s = a.projection_on_contact;  // where the part lies in the view
  j["contact"] = {{"largest_px", s.largest_px},
                  {"at_pixel", {s.largest_at_px.x(), s.largest_at_px.y()}},
                  {"median_px", s.median_px},
                  {"fraction_above_threshold", s.fraction_above},
                  {"threshold_px", s.threshold_px}};
  j["position_uncertainty"] = "from the camera model's projection uncertainty through the inverse map: in the sigma of every texel as "
                              "|grad signal| x the skin position's sigma, in quadrature with the pose's";
  return j;
}

/// The files the run read, each with its role and SHA-256.
json inputs_json(const AssessmentContext& c) {
  json inputs = json::array();
  for (const auto& in : c.inputs) inputs.push_back({{"role", in.role}, {"path", in.path}, {"sha256", in.sha256}});
  return inputs;
}

/// One hotspot: where it is, its size, its level at each threshold, and its pressure (kPa) or, without a
/// calibration, its signal (the kPa keys then null).
json hotspot_json(const Hotspot& h, bool calibrated) {
  const double seen_and_unseen = h.area_mm2 + h.unseen_area_mm2;
  json j = {{"id", h.id},
            {"area_mm2", num(h.area_mm2)},
            {"half_peak_area_mm2", num(h.half_peak_area_mm2)},
            {"centroid_mm", vec(h.centroid_mm)},
            {"centroid_sigma_mm", num(h.centroid_sigma_mm)},
            {"centroid_mean_mm", vec(h.centroid_mean_mm)},
            {"centre_of_pressure_mm", vec(h.centre_of_pressure_mm)},
            {"centre_of_pressure_sigma_mm", num(h.centre_of_pressure_sigma_mm)},
            {"centroid_uv_mm", vec(h.centroid_uv_mm)},
            {"unseen_area_mm2", num(h.unseen_area_mm2)},
            {"unseen_share", num(seen_and_unseen > 0 ? h.unseen_area_mm2 / seen_and_unseen : 0.0)},
            {"faces", h.faces},
            {"texels", h.texels},
            {"saturated_texels", h.flagged_texels},
            {"touches_glare", h.touches_mask}};
  const std::string unit = calibrated ? "_kpa" : "_signal";
  json levels = json::array();
  for (const HotspotLevel& l : h.levels)
    levels.push_back({{"threshold" + unit, num(l.threshold)},
                      {"area_mm2", num(l.area_mm2)},
                      {"area_sigma_mm2", num(l.area_sigma_mm2)},
                      {"mean" + unit, num(l.mean)},
                      {"mean_sigma" + unit, num(l.mean_sigma)},
                      {"texels", l.texels}});
  j["levels"] = levels;
  // Without a calibration the kPa keys are there, null, beside the signal's.
  const std::pair<const char*, double> values[] = {
      {"threshold", h.threshold}, {"peak", h.peak}, {"peak_sigma", h.peak_sigma}, {"mean", h.mean}, {"mean_sigma", h.mean_sigma}};
  for (const auto& [name, v] : values) {
    j[name + unit] = num(v);
    if (!calibrated) j[std::string(name) + "_kpa"] = nullptr;
  }
  return j;
}

json part_json(const AssessmentScene& scene, const AssessmentContext& c) {
  return {{"mesh", c.mesh_name},
          {"vertices", scene.mesh->vertices.size()},
          {"faces", scene.mesh->faces.size()},
          {"ior", num(c.ior)},
          {"medium_ior", num(c.medium_ior)},
          {"contact_faces", scene.contact->faces.size()},
          {"contact_area_mm2", num(scene.contact->area_mm2)},
          {"fast_path", c.fast_path}};
}

json chart_json(const Chart& chart, const ChartGrid& g, const AssessmentContext& c) {
  return {{"texel_mm", g.texel_mm},
          {"width", g.width},
          {"height", g.height},
          {"uv_min_mm", vec(Vec2(g.uv_origin))},
          {"uv_max_mm", vec(Vec2(g.uv(g.width - 1, g.height - 1)))},
          {"method", c.chart_method},
          {"area_ratio_min", num(chart.area_ratio_min)},
          {"area_ratio_max", num(chart.area_ratio_max)}};
}

/// How much of the contact surface was seen, why the rest was not, and how much of the pressed area
/// (the hotspots') lies where the camera does not see.
json coverage_json(const Coverage& cov, const std::vector<Hotspot>& hotspots) {
  double pressed_seen = 0, pressed_unseen = 0;
  for (const Hotspot& h : hotspots) pressed_seen += h.area_mm2, pressed_unseen += h.unseen_area_mm2;
  const double contact = std::max(cov.contact_area_mm2, 1e-12);
  const bool tir = cov.blocked_reason == "contact_tir" || cov.blocked_reason == "entry_tir";
  return {{"contact_area_mm2", num(cov.contact_area_mm2)},
          {"seen_area_mm2", num(cov.seen_area_mm2)},
          {"seen_fraction", num(cov.seen_area_mm2 / contact)},
          {"hidden_fraction",
           {{"total_internal_reflection", num(tir ? cov.hidden_blocked_mm2 / contact : 0.0)},
            {"outside_view", num(cov.hidden_outside_view_mm2 / contact)},
            {"other", num(tir ? 0.0 : cov.hidden_blocked_mm2 / contact)},
            {"glare", num(cov.glare_masked_mm2 / contact)}}},
          {"glare_masked_mm2", num(cov.glare_masked_mm2)},
          {"blocked_reason", cov.blocked_reason},
          {"pressed_seen_mm2", num(pressed_seen)},
          {"pressed_unseen_mm2", num(pressed_unseen)},
          {"pressed_unseen_share", num(pressed_seen + pressed_unseen > 0 ? pressed_unseen / (pressed_seen + pressed_unseen) : 0.0)}};
}

/// The signal on the chart: its reference and noise, the area blanched beyond 3 σ on the part, the mean of
/// the plain (uncorrected) difference, and the colour range of its pictures.
json signal_json(const Assessment& a) {
  const ChartGrid& g = a.signal.y.grid;
  double blanched = 0;
  double plain_sum = 0;
  long long plain_n = 0;
  for (std::size_t k = 0; k < g.size(); ++k) {
    const float y = a.signal.y.value[k];
    if (!std::isfinite(y)) continue;
    if (y > 3 * std::max(a.signal.sigma_y.value[k], 1e-6f) && a.raster.face[k] >= 0) blanched += a.raster.area_mm2[k];
    if (std::isfinite(a.signal.plain_difference.value[k])) plain_sum += a.signal.plain_difference.value[k], ++plain_n;
  }
  const auto [slo, shi] = signal_range(a.signal);
  return {{"feature", "log_green_ratio"},
          {"reference", a.signal.reference},
          {"reference_log_ratio", num(a.signal.reference_log_ratio)},
          {"noise_sigma", num(a.signal.noise_sigma)},
          {"noise_sigma_temporal", num(a.signal.temporal_noise_sigma)},
          {"noise_sigma_spatial", num(a.signal.spatial_noise_sigma)},
          {"blanched_area_mm2", num(blanched)},
          {"plain_difference_mean", plain_n ? num(plain_sum / plain_n) : json(nullptr)},
          {"range", {slo, shi}}};
}

/// The wearer's pressure calibration as used, or null without one.
json pressure_calibration_json(const AssessmentContext& c) {
  if (!c.calibration) return nullptr;
  const PressureCalibration& p = *c.calibration;
  return {{"source", p.path.string()},
          {"person", p.person},
          {"model", to_string(p.model)},
          {"y_max", num(p.logistic.y_max)},
          {"p50_kpa", num(p.logistic.p50_kpa)},
          {"width_kpa", num(p.logistic.width_kpa)},
          {"noise_sigma", num(p.noise_sigma)},
          {"rmse_kpa", num(p.rmse_kpa)},
          {"r2", num(p.r2)},
          {"linear_r2", num(p.r2_linear)},
          {"reference_r2", 0.439},
          {"presses", p.presses},
          {"range_kpa", {num(p.p_min_kpa), num(p.p_max_kpa)}}};
}

/// The pressure field's summary and colour range, or null without a calibration.
json pressure_json(const Assessment& a, const AssessmentContext& c) {
  if (!a.calibrated) return nullptr;
  const auto [lo, hi] = pressure_range(c);
  return {{"unit", "kPa"},
          {"colormap", "viridis"},
          {"range_kpa", {lo, hi}},
          {"peak_kpa", num(a.peak_kpa)},
          {"mean_kpa", num(a.mean_kpa)},
          {"below_detection_fraction", num(a.below_detection_fraction)},
          {"detection_limit_kpa", num(a.detection_limit.kpa)},
          {"detection_limit_signal", num(a.detection_limit.signal)},
          {"saturated_fraction", num(a.saturated_fraction)}};
}

/// The files written beside report.json (those of the pressure view, the registration and the timeline only
/// when they were made).
json outputs_json(const Assessment& a) {
  json outputs = {{"heatmap_glb", "heatmap.glb"},
                  {"chart_pressure_png", "chart_pressure.png"},
                  {"chart_signal_png", "chart_signal.png"},
                  {"skin_camera_png", "skin_camera.png"},
                  {"skin_chart_png", "skin_chart.png"},
                  {"pressure_npy", "pressure.npy"},
                  {"pressure_sigma_npy", "pressure_sigma.npy"},
                  {"signal_npy", "signal.npy"},
                  {"chart_points_npy", "chart_points.npy"},
                  {"hotspots_csv", "hotspots.csv"},
                  {"vertices_csv", "vertices.csv"},
                  {"heatmap_ply", "heatmap.ply"}};
  if (a.calibrated) outputs["heatmap_signal_glb"] = "heatmap_signal.glb";
  if (a.phase_registration.applied) outputs["displacement_npy"] = "displacement.npy";
  if (!a.gap_signal_sigma.value.empty()) outputs["signal_sigma_from_gap_npy"] = "signal_sigma_from_gap.npy";
  if (a.time.present) {
    outputs["timeline_csv"] = "timeline.csv";
    outputs["timeline_time_npy"] = "timeline_time_s.npy";
    outputs["timeline_texels_signal_npy"] = "timeline_texels_signal.npy";
    if (a.calibrated) outputs["timeline_texels_pressure_npy"] = "timeline_texels_pressure_kpa.npy";
  }
  return outputs;
}

/// Where one video holding both phases was split (frames), or null with two videos.
json split_json(const Assessment& a) {
  if (!a.split) return nullptr;
  return {{"press_frame", a.split->press_frame}, {"settled_frame", a.split->settled_frame}, {"step_sigmas", num(a.split->step_sigmas)},
          {"release_frame", a.split->release_frame >= 0 ? json(a.split->release_frame) : json(nullptr)}};
}

}  // namespace

json assessment_report_json(const Assessment& a, const AssessmentScene& scene, const AssessmentContext& c) {
  json hotspots = json::array();
  for (const Hotspot& h : a.hotspots) hotspots.push_back(hotspot_json(h, a.calibrated));
  return {
      {"schema", "clearfit.report/1"},
      {"clearfit_version", c.clearfit_version},
      {"created_utc", utc_now()},
      {"run_time_s", num(c.run_time_s)},
      {"scene", c.scene},
      {"options", c.options},
      {"inputs", inputs_json(c)},
      {"part", part_json(scene, c)},
      {"chart", chart_json(*scene.chart, a.signal.y.grid, c)},
      {"coverage", coverage_json(a.coverage, a.hotspots)},
      {"captures", {{"baseline", phase_json(a.baseline)}, {"worn", phase_json(a.worn)}, {"split", split_json(a)}}},
      {"glare", glare_json(a.glare, a.coverage)},
      {"baseline_geometry", baseline_geometry_json(a.baseline_geometry)},
      {"phase_move", phase_move_json(a.phase_move)},
      {"phase_registration", phase_registration_json(a.phase_registration)},
      {"signal", signal_json(a)},
      {"calibration",
       {{"camera", {{"rms_px", nullptr}, {"source", c.camera_source}}},
        {"pose", pose_json(a, scene, c)},
        {"camera_intrinsics", intrinsics_json(a, scene)},
        {"pressure", pressure_calibration_json(c)}}},
      {"pressure", pressure_json(a, c)},
      {"thresholds_kpa", a.calibrated ? json(a.thresholds) : json::array()},
      {"thresholds_signal", a.calibrated ? json::array() : json(a.thresholds)},
      {"hotspots", hotspots},
      {"timeline", timeline_json(a)},
      {"warnings", a.warnings},
      {"timings_ms", {{"decode_wait", num(a.read_ms)}, {"accumulate", num(a.work_ms)}, {"assessment", num(a.total_ms)}}},
      {"outputs", outputs_json(a)}};
}

std::vector<std::string> write_assessment_outputs(const Assessment& a, const AssessmentScene& scene,
                                                  const CornerNormals& normals, const AssessmentContext& c,
                                                  const std::filesystem::path& folder) {
  std::vector<std::string> written;
  const auto [lo, hi] = pressure_range(c);
  const auto [slo, shi] = signal_range(a.signal);

  std::vector<HeatmapMarker> markers;
  for (const Hotspot& h : a.hotspots)
    if (h.centroid_mm.allFinite())
      markers.push_back(
          {h.id, h.centroid_mm,
           a.calibrated ? "hotspot " + std::to_string(h.id) + ": peak " + fixed_digits(h.peak, 1) + " kPa"
                        : "hotspot " + std::to_string(h.id) + ": blanching"});
  const std::vector<std::uint8_t> seen = vertex_seen(a, *scene.chart);
  auto glb = [&](bool pressure_view, const std::string& name) {
    HeatmapInput in;
    in.mesh = scene.mesh;
    in.normals = &normals;
    in.chart = scene.chart;
    in.values = pressure_view ? a.vertex_pressure : a.vertex_signal;
    const std::vector<float> zeros(a.vertex_signal.size(), 0.f);
    in.scalars = {{"_PRESSURE_KPA", a.calibrated ? a.vertex_pressure : zeros},
                  {"_PRESSURE_SIGMA_KPA", a.calibrated ? a.vertex_pressure_sigma : zeros},
                  {"_BLANCH", a.vertex_signal}};
    in.texture = pressure_view ? &a.pressure : &a.signal.y;
    in.quantity = pressure_view ? "pressure_kpa" : "signal";
    in.unit = pressure_view ? "kPa" : "";
    in.range_lo = pressure_view ? lo : slo;
    in.range_hi = pressure_view ? hi : shi;
    in.hotspots = markers;
    in.seen.assign(seen.begin(), seen.end());
    write_heatmap_glb(in, folder / name);
    written.push_back(name);
  };
  if (a.calibrated) {
    glb(true, "heatmap.glb");
    glb(false, "heatmap_signal.glb");
  } else {
    glb(false, "heatmap.glb");
  }
  auto chart_png = [&](const ChartField& f, double l, double h, const std::string& unit, const std::string& title,
                       const std::string& name) {
    ChartImageInput in;
    in.field = &f;
    in.range_lo = l;
    in.range_hi = h;
    in.unit = unit;
    in.title = title;
    in.hotspot_labels = a.hotspot_labels;
    write_chart_heatmap_png(in, folder / name);
    written.push_back(name);
  };
  if (a.calibrated)
    chart_png(a.pressure, lo, hi, "kPa", "Pressure on the contact surface (kPa)", "chart_pressure.png");
  else
    chart_png(a.signal.y, slo, shi, "", "Blanching signal (no pressure calibration)", "chart_pressure.png");
  chart_png(a.signal.y, slo, shi, "", "Blanching signal ln(G/G0), reference-normalised", "chart_signal.png");
  write_hotspots_csv(a, folder / "hotspots.csv");
  write_vertex_csv(a, *scene.mesh, *scene.chart, folder / "vertices.csv");
  write_vertex_ply(a, *scene.mesh, *scene.chart, folder / "heatmap.ply");
  for (const char* f : {"hotspots.csv", "vertices.csv", "heatmap.ply"}) written.push_back(f);
  write_png(a.skin_camera, folder / "skin_camera.png");
  written.push_back("skin_camera.png");
  cv::Mat chart_up;
  cv::flip(a.skin_chart, chart_up, 0);  // v up, as in the chart heatmaps
  write_png(chart_up, folder / "skin_chart.png");
  written.push_back("skin_chart.png");
  write_field_npy(a.calibrated ? a.pressure : a.signal.y, folder / "pressure.npy");
  write_field_npy(a.signal.y, folder / "signal.npy");
  write_field_npy(a.calibrated ? a.pressure_sigma : a.signal.sigma_y, folder / "pressure_sigma.npy");
  written.push_back("pressure.npy");
  written.push_back("pressure_sigma.npy");
  written.push_back("signal.npy");
  if (!a.gap_signal_sigma.value.empty()) {
    write_field_npy(a.gap_signal_sigma, folder / "signal_sigma_from_gap.npy");
    written.push_back("signal_sigma_from_gap.npy");
  }
  if (a.phase_registration.applied) {
    // The skin's displacement from the not-worn to the worn capture: H x W x 2 (u, v) chart mm, NaN unseen.
    const ChartGrid& g = a.phase_registration.dx_mm.grid;
    npy::write_float32(folder / "displacement.npy", {std::size_t(g.height), std::size_t(g.width), 2}, [&](std::size_t row, float* out) {
      for (int i = 0; i < g.width; ++i)
        out[2 * i] = a.phase_registration.dx_mm.value[row * g.width + i], out[2 * i + 1] = a.phase_registration.dy_mm.value[row * g.width + i];
    });
    written.push_back("displacement.npy");
  }
  if (a.raster.grid.size() == a.signal.y.grid.size() && a.raster.point.size() == a.raster.grid.size()) {
    // Where each texel lies on the part (part frame, mm): profiles and plots in the part's own coordinates.
    const ChartGrid& g = a.raster.grid;
    npy::write_float32(folder / "chart_points.npy", {std::size_t(g.height), std::size_t(g.width), 3}, [&](std::size_t row, float* out) {
      for (int i = 0; i < g.width; ++i)
        for (int k = 0; k < 3; ++k) out[3 * i + k] = static_cast<float>(a.raster.point[row * g.width + i][k]);
    });
    written.push_back("chart_points.npy");
  }
  for (const auto& f : write_timeline_outputs(a, folder)) written.push_back(f);
  write_file_atomically(folder / "report.json", assessment_report_json(a, scene, c).dump(2) + "\n");
  written.push_back("report.json");
  return written;
}

}  // namespace clearfit
