// Calibration presses through the forward model, and the truth files.
#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/npy.hpp>
#include <clearfit/fit/contact_mechanics.hpp>
#include <clearfit/fit/simulate.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <sstream>

namespace clearfit::sim {

namespace {
constexpr double kPi = std::numbers::pi;
using json = nlohmann::json;

// Relative SD of the feature y of one press: per-pixel relative noise of the green channel
// averaged over the disc's pixels and `frames` frames, for the four averages in
// y = ln[(G/G0)/(G_ref/G_ref0)] (the reference region as large as the disc).
double press_signal_sd(const SkinParameters& skin, const CameraSettings& cam, const PressOptions& o, double diameter_mm) {
  const double level = cam.exposure * skin.tone.reflectance[1];
  const double rel = std::sqrt(level * cam.full_well_e + cam.read_noise_e * cam.read_noise_e) / (cam.full_well_e * level);
  const double pixels = kPi * 0.25 * diameter_mm * diameter_mm * o.px_per_mm * o.px_per_mm;
  return rel * std::sqrt(4.0 / (pixels * o.frames));
}

json vec(const Vec2& v) { return {v.x(), v.y()}; }
json vec(const Vec3& v) { return {v.x(), v.y(), v.z()}; }
json skin_json(const SkinParameters& s) {
  return {{"tone", s.tone.name},
          {"reflectance_rgb", {s.tone.reflectance[0], s.tone.reflectance[1], s.tone.reflectance[2]}},
          {"blur_sigma_mm", s.blur_sigma_mm},
          {"von_mises_weight", s.von_mises_weight},
          {"von_mises_depth_mm", s.von_mises_depth_mm},
          {"poisson", s.poisson},
          {"s50_kpa", s.s50_kpa},
          {"width_kpa", s.width_kpa},
          {"beta", s.beta},
          {"tau_on_s", s.tau_on_s},
          {"tau_off_s", s.tau_off_s},
          {"pulse_amplitude", s.pulse_amplitude},
          {"pulse_hz", s.pulse_hz},
          {"absorption_rgb", {s.absorption[0], s.absorption[1], s.absorption[2]}},
          {"ridge_period_mm", s.ridge_period_mm},
          {"ridge_amplitude", s.ridge_amplitude},
          {"ridge_warp_mm", s.ridge_warp_mm},
          {"mottling_amplitude", s.mottling_amplitude},
          {"mottling_scale_mm", s.mottling_scale_mm},
          {"texture_seed", s.texture_seed}};
}
json calibration_json(const SkinParameters& s) {
  const EquivalentCalibration c = equivalent_calibration(s);
  return {{"model", "logistic"},
          {"y_max", c.y_max},
          {"p50_kpa", c.p50_kpa},
          {"width_kpa", c.width_kpa},
          {"feature", "y = ln[(G/G0)/(G_ref/G_ref0)]"},
          {"note", "exact for the skin drive (pressure blurred by blur_sigma_mm, mixed with von Mises when "
                   "von_mises_weight > 0); equals the contact pressure where it varies slowly"}};
}
json camera_json(const CameraSettings& c) {
  return {{"exposure", c.exposure},           {"full_well_e", c.full_well_e},
          {"read_noise_e", c.read_noise_e},   {"falloff", c.falloff},
          {"specular_peak", c.specular_peak}, {"specular_center", vec(c.specular_center)},
          {"specular_sigma", c.specular_sigma}, {"background", c.background},
          {"flicker_amplitude", c.flicker_amplitude}, {"flicker_hz", c.flicker_hz},
          {"motion_step_px", c.motion_step_px}, {"motion_drift_px_per_s", c.motion_drift_px_per_s},
          {"motion_tremor_px", c.motion_tremor_px}, {"motion_tremor_hz", c.motion_tremor_hz},
          {"motion_rotation_deg", c.motion_rotation_deg}, {"supersample", c.supersample},
          {"texture_mm", c.texture_mm}};
}
}  // namespace

void PressOptions::validate() const {
  if (diameters_mm.empty()) throw std::invalid_argument("PressOptions.diameters_mm must not be empty");
  for (double d : diameters_mm)
    if (!(d > 0 && d < 50)) throw std::invalid_argument("PressOptions.diameters_mm: each must be in (0, 50) mm");
  if (levels < 2) throw std::invalid_argument("PressOptions.levels must be >= 2");
  if (!(max_kpa > 0 && max_kpa < 1000)) throw std::invalid_argument("PressOptions.max_kpa must be in (0, 1000)");
  if (repetitions < 1) throw std::invalid_argument("PressOptions.repetitions must be >= 1");
  if (frames < 1) throw std::invalid_argument("PressOptions.frames must be >= 1");
  if (!(px_per_mm > 0)) throw std::invalid_argument("PressOptions.px_per_mm must be > 0");
  if (!(trial_jitter >= 0 && trial_jitter < 1)) throw std::invalid_argument("PressOptions.trial_jitter must be in [0, 1)");
  if (!(offset_sd >= 0 && offset_sd < 1)) throw std::invalid_argument("PressOptions.offset_sd must be in [0, 1)");
  if (!(ring_mm == 0 || (ring_mm >= 0.01 && ring_mm <= 5))) throw std::invalid_argument("PressOptions.ring_mm must be 0 or in [0.01, 5] mm");
}

namespace {
/// The noiseless response of one press: the disc's mean signal and, for the
/// sneddon profile with rings, each ring's mean signal.
struct PressResponse {
  double disc = 0;
  std::vector<double> edges, rings;
};

/// Sneddon's flat-punch pressure (force F, radius a) averaged over the annulus r ± h/2, kPa.
double sneddon_annulus_kpa(double force_n, double a, double r, double h) {
  const double r0 = std::max(0.0, r - h / 2), r1 = r + h / 2;
  if (r0 >= a) return 0;
  auto inside = [&](double rr) { return rr >= a ? 1.0 : 1 - std::sqrt(1 - rr * rr / (a * a)); };  // share of F within rr
  return 1000 * force_n * (inside(r1) - inside(r0)) / (kPi * (r1 * r1 - r0 * r0));
}

PressResponse press_response(const SkinParameters& skin, const PressOptions& o, double radius_mm, double mean_kpa) {
  const double kg = skin.absorption[1];
  PressResponse out;
  out.disc = kg * steady_blood_loss(skin, mean_kpa);
  if (o.profile != PressOptions::Profile::sneddon) return out;
  const double margin = 1.0;  // as `clearfit presses` (SessionOptions::profile_margin_mm)
  if (o.ring_mm > 0)
    for (double e = 0; e < radius_mm + margin + 1e-9; e += o.ring_mm) out.edges.push_back(e);
  const std::size_t rings = out.edges.empty() ? 0 : out.edges.size() - 1;
  std::vector<double> sum(rings, 0.0), count(rings, 0.0);
  if (mean_kpa <= 0) {  // no press: every ring reads the unpressed skin
    out.rings.assign(rings, out.disc);
    return out;
  }
  // Sneddon's field, each grid cell given the mean over the annulus of its radius ± h/2 (exact: the
  // force inside r is F·(1 − √(1 − r²/a²))), so the rim's integrable singularity keeps its share of the
  // force the gauge reads. Capping it instead (at 3·p_mean) dropped 1/12 of the force and biased the
  // fitted p50 by +7 %.
  const double force_n = mean_kpa * kPi * radius_mm * radius_mm / 1000;
  ChartField field;
  const double h = std::min(0.05, radius_mm / 20), m = radius_mm + margin + 4 * skin.blur_sigma_mm + 0.5;
  field.grid = ChartGrid::covering(Vec2(-m, -m), Vec2(m, m), h);
  field.value.resize(field.grid.size());
  for (int j = 0; j < field.grid.height; ++j)
    for (int i = 0; i < field.grid.width; ++i)
      field.value[field.grid.index(i, j)] = static_cast<float>(sneddon_annulus_kpa(force_n, radius_mm, field.grid.uv(i, j).norm(), h));
  const ChartField drive = skin_drive(skin, field);
  double disc = 0;
  int n = 0;
  for (int j = 0; j < field.grid.height; ++j)
    for (int i = 0; i < field.grid.width; ++i) {
      const double r = field.grid.uv(i, j).norm();
      const double y = kg * steady_blood_loss(skin, drive.value[field.grid.index(i, j)]);
      if (r < radius_mm) disc += y, ++n;
      if (rings > 0 && r < out.edges.back()) {
        const auto k = static_cast<std::size_t>(std::upper_bound(out.edges.begin(), out.edges.end(), r) - out.edges.begin()) - 1;
        sum[k] += y, count[k] += 1;
      }
    }
  out.disc = disc / n;
  for (std::size_t k = 0; k < rings; ++k) out.rings.push_back(count[k] > 0 ? sum[k] / count[k] : out.disc);
  return out;
}
}  // namespace

std::vector<PressTrial> simulate_presses(const SkinParameters& skin, const CameraSettings& cam, const PressOptions& o,
                                         std::uint64_t seed) {
  skin.validate();
  cam.validate();
  o.validate();
  std::map<std::pair<int, int>, PressResponse> noiseless;  // (diameter index, level) → response
  for (std::size_t di = 0; di < o.diameters_mm.size(); ++di)
    for (int l = 0; l < o.levels; ++l)
      noiseless[{static_cast<int>(di), l}] = press_response(skin, o, o.diameters_mm[di] / 2, o.max_kpa * l / (o.levels - 1));
  std::mt19937_64 rng(seed ^ 0x7072657373ULL);
  std::mt19937_64 ring_rng(seed ^ 0x72696e6773ULL);  // own stream: the disc signals stay as without profiles
  std::normal_distribution<double> normal(0, 1);
  std::vector<PressTrial> trials;
  int trial = 0;
  for (int rep = 0; rep < o.repetitions; ++rep)
    for (std::size_t di = 0; di < o.diameters_mm.size(); ++di)
      for (int l = 0; l < o.levels; ++l) {
        const PressResponse& y = noiseless[{static_cast<int>(di), l}];
        PressTrial t;
        t.trial = ++trial;
        t.diameter_mm = o.diameters_mm[di];
        t.mean_pressure_kpa = o.max_kpa * l / (o.levels - 1);
        t.force_n = t.mean_pressure_kpa * kPi * 0.25 * t.diameter_mm * t.diameter_mm / 1000;
        t.signal_noiseless = y.disc;
        const double gain = 1 + o.trial_jitter * normal(rng), offset = o.offset_sd * normal(rng);
        const double disc_sd = press_signal_sd(skin, cam, o, t.diameter_mm);
        t.signal = y.disc * gain + offset + disc_sd * normal(rng);
        // Each ring: the press's gain and offset, and the sensor noise of its own area.
        t.ring_edges_mm = y.edges;
        const double disc_area = kPi * 0.25 * t.diameter_mm * t.diameter_mm;
        for (std::size_t k = 0; k < y.rings.size(); ++k) {
          const double area = kPi * (y.edges[k + 1] * y.edges[k + 1] - y.edges[k] * y.edges[k]);
          t.ring_signal.push_back(y.rings[k] * gain + offset + disc_sd * std::sqrt(disc_area / area) * normal(ring_rng));
        }
        trials.push_back(t);
      }
  return trials;
}

void write_presses_csv(const std::vector<PressTrial>& trials, const std::filesystem::path& path) {
  const bool profiles = !trials.empty() && std::all_of(trials.begin(), trials.end(), [](const PressTrial& t) { return !t.ring_signal.empty(); });
  auto list = [](const std::vector<double>& v) {
    std::ostringstream s;
    s.precision(9);
    for (std::size_t k = 0; k < v.size(); ++k) s << (k ? ";" : "") << v[k];
    return s.str();
  };
  std::ostringstream s;
  s.precision(9);
  s << "trial,indenter_diameter_mm,force_n,mean_pressure_kpa,signal" << (profiles ? ",ring_edges_mm,ring_signal" : "") << "\n";
  for (const PressTrial& t : trials) {
    s << t.trial << ',' << t.diameter_mm << ',' << t.force_n << ',' << t.mean_pressure_kpa << ',' << t.signal;
    if (profiles) s << ',' << list(t.ring_edges_mm) << ',' << list(t.ring_signal);
    s << '\n';
  }
  write_file_atomically(path, s.str());
}

void write_presses_truth(const std::filesystem::path& path, const SkinParameters& skin, const CameraSettings& cam,
                         const PressOptions& o, std::uint64_t seed) {
  json sd = json::object();
  for (double d : o.diameters_mm) {
    std::ostringstream k;
    k << d;
    sd[k.str()] = press_signal_sd(skin, cam, o, d);
  }
  const json j = {{"schema", "clearfit.presses-truth/1"},
                  {"seed", seed},
                  {"skin", skin_json(skin)},
                  {"calibration", calibration_json(skin)},
                  {"presses",
                   {{"diameters_mm", o.diameters_mm},
                    {"levels", o.levels},
                    {"max_kpa", o.max_kpa},
                    {"repetitions", o.repetitions},
                    {"profile", o.profile == PressOptions::Profile::sneddon ? "sneddon" : "uniform"},
                    {"frames", o.frames},
                    {"px_per_mm", o.px_per_mm},
                    {"trial_jitter", o.trial_jitter},
                    {"offset_sd", o.offset_sd},
                    {"sensor_signal_sd_by_diameter", sd}}},
                  {"note", "profile uniform: signal = y_max·Ψ((p − p50)/w)·(1 + jitter) + noise exactly; sneddon: the "
                           "disc carries Sneddon's pressure (capped at 3·p_mean) through the skin drive, so the "
                           "signal at a mean pressure departs from the logistic"}};
  write_file_atomically(path, j.dump(2) + "\n");
}

void write_truth(const std::filesystem::path& dir, const PressureFieldSpec& spec, const PressureTruth& truth,
                 const SkinParameters& skin, const CameraSettings& cam, const Timeline& tl, const CaptureSummary& cap,
                 VideoFormat format, cv::Size size, std::uint64_t seed,
                 const std::vector<std::pair<std::string, std::string>>& inputs) {
  const ChartGrid& g = truth.pressure.grid;
  json sources = json::array();
  for (std::size_t k = 0; k < spec.sources.size(); ++k) {
    const PressureSource& s = spec.sources[k];
    json j = {{"name", s.name}, {"type", s.kind_name()}, {"center_uv_mm", vec(truth.source_uv_mm[k])}};
    j["center_part_mm"] = truth.source_part_mm[k] ? vec(*truth.source_part_mm[k]) : json(nullptr);
    if (s.kind == PressureSource::Kind::gaussian) j["peak_kpa"] = s.peak_kpa, j["sigma_mm"] = s.sigma_mm;
    if (s.kind == PressureSource::Kind::punch)
      j["radius_mm"] = s.radius_mm, j["force_n"] = s.force_n, j["rim_cap_ratio"] = s.rim_cap_ratio,
      j["mean_pressure_kpa"] = contact::mean_pressure_kpa(s.force_n, s.radius_mm);
    if (s.kind == PressureSource::Kind::hertz) {
      const contact::HertzSphere h{s.sphere_radius_mm, s.force_n, s.e_star_kpa};
      j["sphere_radius_mm"] = s.sphere_radius_mm, j["force_n"] = s.force_n, j["e_star_kpa"] = s.e_star_kpa,
      j["contact_radius_mm"] = h.contact_radius_mm(), j["peak_pressure_kpa"] = h.peak_pressure_kpa();
    }
    sources.push_back(j);
  }
  json hotspots = json::array();
  for (const Hotspot& h : truth.hotspots)
    hotspots.push_back({{"centroid_uv_mm", vec(h.centroid_uv_mm)},
                        {"centroid_part_mm", h.centroid_part_mm ? vec(*h.centroid_part_mm) : json(nullptr)},
                        {"peak_kpa", h.peak_kpa},
                        {"area_ge_5_5_kpa_mm2", h.area_above_5_5_mm2},
                        {"area_ge_4_3_kpa_mm2", h.area_above_4_3_mm2}});
  json phases = json::array();
  if (tl.single_video) {
    phases.push_back({{"phase", "baseline"}, {"file", cap.files[0]}, {"first_frame", 0}, {"frames", cap.baseline_frames}});
    phases.push_back({{"phase", "worn"}, {"file", cap.files[0]}, {"first_frame", cap.baseline_frames}, {"frames", cap.press_frames}});
  } else {
    phases.push_back({{"phase", "baseline"}, {"file", cap.files[0]}, {"first_frame", 0}, {"frames", cap.baseline_frames}});
    phases.push_back({{"phase", "worn"}, {"file", cap.files[1]}, {"first_frame", 0}, {"frames", cap.press_frames}});
  }
  if (cap.release_frames > 0)
    phases.push_back({{"phase", "released"}, {"file", cap.files.back()},
                      {"first_frame", (tl.single_video ? cap.baseline_frames : 0) + cap.press_frames}, {"frames", cap.release_frames}});
  json shifts = json::array();
  for (const Vec2& s : cap.shift_px) shifts.push_back(vec(s));
  json angles = json::array();
  for (double a : cap.angle_rad) angles.push_back(a * 180 / std::numbers::pi);
  json in = json::object();
  for (const auto& [k, v] : inputs) in[k] = v;
  const json j = {
      {"schema", "clearfit.simulation-truth/1"},
      {"seed", seed},
      {"inputs", in},
      {"chart_grid", {{"texel_mm", g.texel_mm}, {"uv_origin_mm", vec(g.uv_origin)}, {"width", g.width}, {"height", g.height}}},
      {"files", {{"pressure", "truth_pressure.npy"}, {"vertex_pressure", "truth_vertex_pressure.npy"}, {"captures", cap.files}}},
      {"pressure_sources", sources},
      {"user_map", spec.user_map.has_value()},
      {"hotspots", hotspots},
      {"hotspot_definition", "8-connected regions of truth pressure >= 4.3 kPa; centroid pressure-weighted; sorted by peak"},
      {"skin", skin_json(skin)},
      {"calibration", calibration_json(skin)},
      {"video",
       {{"format", to_string(format)},
        {"codec", format == VideoFormat::h264
                      ? json{{"encoder", "libx264"}, {"crf", tl.crf}, {"preset", "fast"}, {"pixel_format", "yuv420p"},
                             {"range", "limited"}, {"matrix", "bt709"}, {"keyframe_interval_s", 1}}
                      : json{{"lossy", format == VideoFormat::mjpg}}},
        {"fps", tl.fps},
        {"width", size.width},
        {"height", size.height},
        {"single_video", tl.single_video},
        {"baseline_frames", cap.baseline_frames},
        {"press_frames", cap.press_frames},
        {"press_start_frame", cap.press_start_frame},
        {"press_start_s", cap.baseline_frames / tl.fps},
        {"release_frames", cap.release_frames},
        {"press_time_s", tl.press_time_s()},
        {"release_time_s", cap.release_frames > 0 ? json(tl.release_time_s()) : json(nullptr)},
        {"phases", phases},
        {"blood_loss_lag", "B(t) = B_ss·h(t), t = frame/fps from the first frame (of the single video; of the baseline video then "
                           "on through the worn one): h = 0 until press_time_s, then 1 − exp(−(t − press_time_s)/tau_on_s); after "
                           "release_time_s (when there are released frames) h(release_time_s)·exp(−(t − release_time_s)/tau_off_s)"}}},
      {"camera", camera_json(cam)},
      {"baseline", {{"part", to_string(cap.baseline.part)},
                    {"gap_mm", cap.baseline.part == BaselinePart::touching ? 0.0 : cap.baseline.gap_mm},
                    {"note", "the not-worn frames: the skin gap_mm beyond the contact surface (along its normals), the part held off "
                             "it, absent, or touching as when worn"}}},
      {"motion", {{"step_px", cam.motion_step_px}, {"drift_px_per_s", cam.motion_drift_px_per_s},
                  {"tremor_px", cam.motion_tremor_px}, {"tremor_hz", cam.motion_tremor_hz},
                  {"rotation_deg", cam.motion_rotation_deg}, {"shift_px_per_frame", shifts},
                  {"rotation_deg_per_frame", angles}, {"centre_px", {0.5 * (size.width - 1), 0.5 * (size.height - 1)}},
                  {"note", "per frame (baseline frames first): the skin at reference pixel q is seen at "
                           "centre + R(rotation)·(q − centre) + shift, px and degrees"}}},
      {"timings_ms", {{"render", cap.render_ms}, {"write_wait", cap.write_ms}}}};
  write_npy_float32(dir / "truth_pressure.npy", {static_cast<std::size_t>(g.height), static_cast<std::size_t>(g.width)},
                    truth.pressure.value.data());
  write_npy_float32(dir / "truth_vertex_pressure.npy", {truth.vertex_pressure.size()}, truth.vertex_pressure.data());
  write_file_atomically(dir / "truth.json", j.dump(2) + "\n");
}

double vertex_pressure_pearson(const std::filesystem::path& vertices_csv, const std::filesystem::path& truth_vertex_npy, int* count) {
  const std::vector<float> truth = npy::read_float32(truth_vertex_npy).values;
  std::ifstream in(vertices_csv);
  if (!in) throw InputError(vertices_csv.string(), "", "cannot be read");
  std::string line;
  std::getline(in, line);  // vertex,x_mm,y_mm,z_mm,contact,seen,pressure_kpa,...
  double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0, n = 0;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream row(line);
    for (std::string c; std::getline(row, c, ',');) f.push_back(c);
    if (f.size() < 7 || f[4] != "1" || f[5] != "1" || f[6].empty()) continue;
    const std::size_t v = std::stoul(f[0]);
    if (v >= truth.size() || !std::isfinite(truth[v])) continue;
    const double a = std::stod(f[6]), b = truth[v];
    sa += a, sb += b, saa += a * a, sbb += b * b, sab += a * b, n += 1;
  }
  if (count) *count = static_cast<int>(n);
  const double den = (saa - sa * sa / n) * (sbb - sb * sb / n);
  return n >= 3 && den > 0 ? (sab - sa * sb / n) / std::sqrt(den) : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace clearfit::sim
