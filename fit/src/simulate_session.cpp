// Synthetic calibration sessions: video of the skin under a clear flat
// indenter, the force gauge's log on its own clock, and the truth
// (calibration_session.hpp).
#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/fit/calibration_session.hpp>
#include <clearfit/fit/contact_mechanics.hpp>
#include <clearfit/fit/srgb.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <numbers>
#include <random>

namespace clearfit::sim {
namespace {

/// The true force (N) at gauge time t: a ramp, an overshoot decaying after it, the hold, a ramp down.
double true_force(const CalibrationSessionSpec& s, const std::vector<SessionPressTruth>& presses, double t) {
  for (const SessionPressTruth& p : presses) {
    if (t <= p.start_s || t >= p.end_s) continue;
    const double up = (t - p.start_s) / s.ramp_s, down = (p.end_s - t) / s.ramp_s;
    if (down < 1) return p.force_n * down;
    if (up < 1) return p.force_n * up * (1 + s.overshoot * up);
    return p.force_n * (1 + s.overshoot * std::exp(-(t - p.start_s - s.ramp_s) / s.overshoot_tau_s));
  }
  return 0;
}

std::vector<SessionPressTruth> schedule(const CalibrationSessionSpec& s, std::mt19937_64& rng) {
  std::vector<double> kpa(s.presses);
  for (int k = 0; k < s.presses; ++k) kpa[k] = s.min_kpa + (s.max_kpa - s.min_kpa) * k / std::max(1, s.presses - 1);
  std::shuffle(kpa.begin(), kpa.end(), rng);
  std::uniform_real_distribution<double> rest(s.rest_min_s, s.rest_max_s);
  const double area_mm2 = std::numbers::pi * s.indenter_radius_mm * s.indenter_radius_mm;
  const double e_star = s.e_star_kpa / 1000;  // N/mm²
  std::vector<SessionPressTruth> out;
  double t = std::max(0.0, s.offset_s) + s.lead_s;
  for (double p : kpa) {
    SessionPressTruth press;
    press.start_s = t;
    press.end_s = t + s.hold_s + 2 * s.ramp_s;
    press.mean_pressure_kpa = p;
    press.force_n = p * area_mm2 / 1000;
    press.contact_radius_mm = s.indenter_radius_mm;
    if (s.sphere_radius_mm > 0) {  // Hertz: p0 = 1.5 p_mean = 2E*a/(πR), F = π a² p_mean
      press.contact_radius_mm = std::numbers::pi * s.sphere_radius_mm * 1.5 * p / 1000 / (2 * e_star);
      press.force_n = std::numbers::pi * press.contact_radius_mm * press.contact_radius_mm * p / 1000;
    }
    out.push_back(press);
    t = press.end_s + rest(rng);
  }
  return out;
}

void write_force_log(const CalibrationSessionSpec& s, const std::vector<SessionPressTruth>& presses, double end_s,
                     std::mt19937_64& rng, const std::filesystem::path& path) {
  std::normal_distribution<double> noise(0, s.force_noise_n);
  write_file_atomically(path, [&](std::ostream& out) {
    out << "time_s,force_n\n";
    out.precision(9);
    for (long i = 0;; ++i) {
      const double t = double(i) / s.gauge_hz;
      if (t > end_s) break;
      const double rest = s.rest_drift_n * std::sin(2 * std::numbers::pi * t / 150);
      out << t << "," << true_force(s, presses, t) + s.tare_n + rest + noise(rng) << "\n";
    }
  });
}

/// The sphere's drive per newton at each pixel's radius for the force of a frame: Hertz's profile of
/// the contact radius the force makes, blurred (one table per force to 1e-4 N).
class SphereDrive {
 public:
  explicit SphereDrive(const CalibrationSessionSpec& s) : s_(s) {}
  void operator()(double force, const std::vector<float>& radius, std::vector<float>& drive_per_n) {
    const long long key = std::llround(force * 1e4);
    if (key <= 0) return;  // no force: the drive's factor is 0
    auto& table = tables_[key];
    if (!table) {
      const double a = contact::HertzSphere{s_.sphere_radius_mm, double(key) * 1e-4, s_.e_star_kpa}.contact_radius_mm();
      table = std::make_unique<IndenterProfile>(PressureField::hertz, a, s_.skin.blur_sigma_mm);
    }
    for (std::size_t i = 0; i < radius.size(); ++i) drive_per_n[i] = static_cast<float>(table->kpa_per_newton(radius[i]));
  }

 private:
  const CalibrationSessionSpec& s_;
  std::map<long long, std::unique_ptr<IndenterProfile>> tables_;
};

}  // namespace

void CalibrationSessionSpec::validate() const {
  auto need = [](bool ok, const char* option, const std::string& rule) {
    if (!ok) throw InputError("", option, rule);
  };
  optics.validate();
  need(width >= 32 && height >= 32 && width <= 4096 && height <= 4096, "--size", "width and height from 32 to 4096 px");
  need(focal_px > 0, "--focal-px", "must be > 0");
  need(indenter_radius_mm > 0 && indenter_radius_mm < 20, "--indenter-radius-mm", "from 0 to 20 mm");
  need(fps >= 5 && fps <= 240, "--fps", "from 5 to 240");
  need(exposure > 0 && exposure <= 1, "--exposure", "in (0, 1]");
  need(noise_levels >= 0, "--noise-levels", "must be >= 0");
  need(presses >= 4 && presses <= 100, "--presses", "from 4 to 100");
  need(hold_s >= 2 && rest_min_s >= 2 && rest_max_s >= rest_min_s, "--hold-s", "hold >= 2 s, rests >= 2 s (min <= max)");
  need(min_kpa >= 0 && max_kpa > min_kpa, "--max-kpa", "mean pressures: 0 <= min < max");
  need(sphere_radius_mm >= 0 && sphere_radius_mm < 1000, "--sphere-radius-mm", "from 0 (a flat punch) to 1000 mm");
  need(e_star_kpa > 0 && e_star_kpa < 1e5, "--e-star-kpa", "from 0 to 100000 kPa");
  if (sphere_radius_mm > 0) {  // the largest contact disc (overshoot included) inside the cap the presses are read over
    const double a = std::numbers::pi * sphere_radius_mm * 1.5 * max_kpa / (2 * e_star_kpa) * std::cbrt(1 + overshoot);
    need(a < indenter_radius_mm, "--max-kpa",
         "the sphere's contact radius at --max-kpa is " + std::to_string(a) + " mm, beyond the cap's radius (--indenter-radius-mm " +
             std::to_string(indenter_radius_mm) + "): lower --max-kpa or raise --e-star-kpa");
  }
  need(ramp_s > 0 && ramp_s < hold_s / 2, "--ramp-s", "between 0 and half the hold");
  need(overshoot >= 0 && overshoot < 1, "--overshoot", "in [0, 1)");
  need(gauge_hz >= 5 && gauge_hz <= 10000, "--gauge-hz", "from 5 to 10000");
  need(std::abs(offset_s) < 60, "--offset-s", "|offset| < 60 s");
  need(std::abs(drift_ppm) < 2000, "--drift-ppm", "|drift| < 2000 ppm");
  need(force_noise_n >= 0 && rest_drift_n >= 0, "--force-noise-n", "noise and rest drift >= 0");
  try {
    skin.validate();
  } catch (const std::invalid_argument& e) {
    throw InputError("", "skin", e.what());
  }
}

CameraModel session_camera(const CalibrationSessionSpec& s) {
  CameraModel cam;
  cam.lensmodel = "LENSMODEL_PINHOLE";
  cam.intrinsics = {s.focal_px, s.focal_px, (s.width - 1) / 2.0, (s.height - 1) / 2.0};
  cam.width = s.width;
  cam.height = s.height;
  return cam;
}

CalibrationSessionTruth render_calibration_session(const CalibrationSessionSpec& s, const std::filesystem::path& out,
                                                   const std::function<void(int, int)>& progress) {
  s.validate();
  std::mt19937_64 rng(s.seed);
  CalibrationSessionTruth truth;
  truth.presses = schedule(s, rng);
  truth.person = equivalent_calibration(s.skin);
  const double drift = s.drift_ppm * 1e-6, gauge_end = truth.presses.back().end_s + s.lead_s;
  const double video_end = (gauge_end - s.offset_s) / (1 + drift);
  truth.frames = static_cast<int>(video_end * s.fps);

  // Per pixel: the skin albedo (green modulation) and the drive per newton.
  const CameraModel cam = session_camera(s);
  const IndenterProfile profile(PressureField::punch, s.indenter_radius_mm, s.skin.blur_sigma_mm);
  const SkinTexture texture(s.skin);
  const int n = s.width * s.height;
  std::vector<float> albedo(n), drive_per_n(n), radius(n);
  double nearest = 1e300;
  for (int v = 0; v < s.height; ++v)
    for (int u = 0; u < s.width; ++u) {
      const Vec2 skin = s.optics.skin_point(cam.unproject(Vec2(u, v)));
      const double r = (skin - s.indenter_centre_mm).norm();
      albedo[v * s.width + u] = static_cast<float>(s.exposure * texture.modulation(skin));
      drive_per_n[v * s.width + u] = static_cast<float>(profile.kpa_per_newton(r));
      radius[v * s.width + u] = static_cast<float>(r);
      if (r < nearest) nearest = r, truth.indenter_centre_px = Vec2(u, v);
    }

  std::filesystem::create_directories(out);
  truth.video = capture_name("session", s.format);
  CaptureWriter writer(out / truth.video, s.format, s.fps, cv::Size(s.width, s.height));
  std::vector<double> blood(n, 0.0);
  SphereDrive sphere_drive(s);
  cv::RNG noise_rng(s.seed ^ 0x5e55109ULL);
  cv::Mat frame(s.height, s.width, CV_8UC3), noise(s.height, s.width, CV_32FC3);
  const double dt = 1 / s.fps;
  for (int f = 0; f < truth.frames; ++f) {
    // The frame shows the skin at tv: its blood followed the force over the interval before it, taken at the
    // interval's middle (the force at tv itself would let the skin answer half a frame early).
    const double tv = f * dt, force = true_force(s, truth.presses, (1 + drift) * (tv - dt / 2) + s.offset_s);
    const double pulse = pulse_waveform(tv, s.skin.pulse_hz);
    if (s.sphere_radius_mm > 0) sphere_drive(force, radius, drive_per_n);
    const Eigen::Vector3d rest = radiance_factor(s.skin, 0, pulse);
    noise_rng.fill(noise, cv::RNG::NORMAL, 0.0, s.noise_levels / 255);
    for (int i = 0; i < n; ++i) {
      const double target = steady_blood_loss(s.skin, force * drive_per_n[i]);
      if (blood[i] != 0 || target != 0) blood[i] = lag_step(s.skin, blood[i], target, dt);
      const Eigen::Vector3d rad = blood[i] == 0 ? rest : radiance_factor(s.skin, blood[i], pulse);
      auto* px = frame.ptr<cv::Vec3b>(i / s.width) + i % s.width;
      const auto& nz = noise.ptr<cv::Vec3f>(i / s.width)[i % s.width];
      for (int c = 0; c < 3; ++c) {  // RGB → BGR
        const double lin = albedo[i] * s.skin.tone.reflectance[c] * rad[c] + nz[c];
        (*px)[2 - c] = static_cast<unsigned char>(std::lround(255 * srgb::from_linear(std::clamp(lin, 0.0, 1.0))));
      }
    }
    writer.write(frame);
    if (progress) progress(f + 1, truth.frames);
  }
  writer.finish();
  write_force_log(s, truth.presses, gauge_end + 2, rng, out / "force.csv");
  write_cameramodel(cam, out / "camera.cameramodel");

  using nlohmann::ordered_json;
  ordered_json presses = ordered_json::array();
  for (const auto& p : truth.presses)
    presses.push_back({{"start_s", p.start_s}, {"end_s", p.end_s}, {"force_n", p.force_n}, {"mean_pressure_kpa", p.mean_pressure_kpa},
                       {"contact_radius_mm", p.contact_radius_mm}});
  const ordered_json j = {
      {"schema", "clearfit.calibration-session-truth/1"},
      {"video", truth.video}, {"force_log", "force.csv"}, {"camera", "camera.cameramodel"},
      {"frames", truth.frames}, {"fps", s.fps}, {"seed", s.seed},
      {"clock", {{"offset_s", s.offset_s}, {"drift_ppm", s.drift_ppm}, {"note", "gauge time = (1 + drift) * video time + offset"}}},
      {"gauge", {{"hz", s.gauge_hz}, {"noise_n", s.force_noise_n}, {"tare_n", s.tare_n}, {"rest_drift_n", s.rest_drift_n},
                 {"overshoot", s.overshoot}}},
      {"indenter", {{"radius_mm", s.indenter_radius_mm}, {"shape", s.sphere_radius_mm > 0 ? "sphere" : "flat"},
                    {"sphere_radius_mm", s.sphere_radius_mm}, {"e_star_kpa", s.e_star_kpa}, {"centre_mm", {s.indenter_centre_mm.x(), s.indenter_centre_mm.y()}},
                    {"centre_px", {truth.indenter_centre_px.x(), truth.indenter_centre_px.y()}},
                    {"slab_mm", s.optics.slab_mm}, {"slab_ior", s.optics.slab_ior}, {"distance_mm", s.optics.distance_mm}}},
      {"person", {{"y_max", truth.person.y_max}, {"p50_kpa", truth.person.p50_kpa}, {"width_kpa", truth.person.width_kpa},
                  {"tone", s.skin.tone.name}, {"blur_sigma_mm", s.skin.blur_sigma_mm}}},
      {"presses", presses}};
  write_file_atomically(out / "truth.json", j.dump(2) + "\n");
  return truth;
}

}  // namespace clearfit::sim
