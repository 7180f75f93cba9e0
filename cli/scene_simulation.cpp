// The scene file's `simulation:` section (clearfit simulate), read by hand:
// lists of pressure sources, skin tone presets and enumerations. Ranges are
// checked as each key is read (the error names its line); the modules'
// validate() checks the combinations (SimulationSection::validate).
#include <clearfit/cli/scene.hpp>
#include <clearfit/cli/simulate_photometric.hpp>

#include <clearfit/error.hpp>

#include <cmath>
#include <sstream>

namespace clearfit::cli {

namespace {

/// simulation.preset: realistic — every real-capture effect the simulator has, each at a
/// plausible strength for a hand-held phone over a wrist (README "The realistic preset"):
/// a slow drift, physiological tremor and a slight roll; one highlight in both phases and
/// one only when worn; ±3 % exposure and white-balance steps with slow drifts; 100 Hz
/// flicker of 3 % whose frequency drifts; the worn skin slid 0.2 mm and bulged 0.1 mm around
/// the pressed places; a phone's H.264 at CRF 23. (The held baseline's 1 mm air gap is the
/// simulator's default with or without the preset.) Keys given in the scene replace the preset's.
void apply_preset(const std::string& name, SimulationSection& o) {
  if (name == "none") return;
  // name == "realistic" (checked by the caller)
  o.format = sim::VideoFormat::h264;
  o.timeline.crf = 23;
  o.skin_motion.slide_mm = Vec2(0.2, 0.1);
  o.skin_motion.bulge_mm = 0.1;
  o.skin_motion.bulge_width_mm = 1.0;
  o.camera.motion_step_px = 0.02;
  o.camera.motion_drift_px_per_s = 0.5;
  o.camera.motion_tremor_px = 0.3;
  o.camera.motion_tremor_hz = 10;
  o.camera.motion_rotation_deg = 0.3;
  o.camera.flicker_amplitude = 0.03;
  o.camera.flicker_hz = 100;
  sim::PhotometricEffects& fx = o.photometric;
  fx.flicker_drift_hz_per_s = 0.2;
  sim::GlareBlob both, worn;
  both.center = Vec2(0.36, 0.6), both.sigma = 0.02, both.peak = 0.15, both.phases = sim::GlareBlob::Phases::both;
  worn.center = Vec2(0.66, 0.42), worn.sigma = 0.015, worn.peak = 0.1, worn.phases = sim::GlareBlob::Phases::worn;
  fx.glare = {both, worn};
  sim::GainStep s1, s2;
  s1.t_s = 1.0, s1.gain = {1.03, 1.03, 1.03};
  s2.t_s = 2.5, s2.gain = {0.98, 1.0, 1.03};
  fx.steps = {s1, s2};
  fx.drift_per_s = {0.005, 0.0, -0.005};
}

class SimulationParser {
 public:
  explicit SimulationParser(const SceneReader& r) : r_(r) {}

  void parse(const YAML::Node& s, SimulationSection& o) {
    r_.only_keys(s, "simulation", {"preset", "seed", "out", "format", "crf", "scale", "timeline", "skin", "camera", "flicker", "motion", "pressure",
                                   "presses", "glare", "exposure", "baseline", "skin_motion"});
    // The preset first: every key read below replaces its value.
    if (auto v = r_.get<std::string>(s, "preset", "simulation.preset", "realistic or none")) {
      if (*v != "realistic" && *v != "none")
        r_.fail(s["preset"], "simulation.preset", "expected realistic (every real-capture effect at a plausible strength) or none, got '" + *v + "'");
      o.preset = *v;
      apply_preset(*v, o);
    }
    if (auto v = r_.get<long long>(s, "seed", "simulation.seed", "a whole number")) {
      if (*v < 0) r_.fail(s["seed"], "simulation.seed", "expected a number >= 0");
      o.seed = static_cast<std::uint64_t>(*v);
    }
    if (auto v = r_.path(s, "out", "simulation.out")) o.out = *v;
    if (auto v = r_.get<std::string>(s, "format", "simulation.format", "ffv1, huffyuv, mjpg, png or h264")) {
      try {
        o.format = sim::parse_video_format(*v);
      } catch (const std::invalid_argument&) {
        r_.fail(s["format"], "simulation.format", "expected ffv1, huffyuv, mjpg, png or h264, got '" + *v + "'");
      }
    }
    if (auto v = r_.get<int>(s, "crf", "simulation.crf", "a whole number 0..51")) {
      if (*v < 0 || *v > 51) r_.fail(s["crf"], "simulation.crf", "expected a whole number 0..51 (libx264's constant rate factor)");
      o.timeline.crf = *v;
    }
    num(s, "scale", "simulation.scale", o.scale, 0.05, 4);
    if (const YAML::Node t = s["timeline"]) {
      r_.only_keys(t, "simulation.timeline", {"fps", "baseline_s", "press_s", "release_s", "single_video"});
      num(t, "fps", "simulation.timeline.fps", o.timeline.fps, 1, 1000);
      num(t, "baseline_s", "simulation.timeline.baseline_s", o.timeline.baseline_s, 1e-3, 3600);
      num(t, "press_s", "simulation.timeline.press_s", o.timeline.press_s, 1e-3, 3600);
      num(t, "release_s", "simulation.timeline.release_s", o.timeline.release_s, 0, 3600);
      if (auto v = r_.get<bool>(t, "single_video", "simulation.timeline.single_video", "true or false")) o.timeline.single_video = *v;
    }
    if (const YAML::Node k = s["skin"]) parse_skin(k, o.skin);
    if (const YAML::Node c = s["camera"]) {
      const std::string p = "simulation.camera";
      r_.only_keys(c, p, {"exposure", "full_well_e", "read_noise_e", "falloff", "specular_peak", "specular_center",
                          "specular_sigma", "background", "supersample", "texture_mm"});
      auto& cam = o.camera;
      num(c, "exposure", p + ".exposure", cam.exposure, 1e-3, 100);
      num(c, "full_well_e", p + ".full_well_e", cam.full_well_e, 1, 1e9);
      num(c, "read_noise_e", p + ".read_noise_e", cam.read_noise_e, 0, 1e4);
      num(c, "falloff", p + ".falloff", cam.falloff, 0, 0.99);
      num(c, "specular_peak", p + ".specular_peak", cam.specular_peak, 0, 10);
      if (c["specular_center"]) cam.specular_center = vec2(c["specular_center"], p + ".specular_center");
      num(c, "specular_sigma", p + ".specular_sigma", cam.specular_sigma, 1e-4, 10);
      num(c, "background", p + ".background", cam.background, 0, 1);
      double ss = cam.supersample;
      num(c, "supersample", p + ".supersample", ss, 1, 4);
      if (ss != std::floor(ss)) r_.fail(c["supersample"], p + ".supersample", "expected a whole number 1..4");
      cam.supersample = static_cast<int>(ss);
      num(c, "texture_mm", p + ".texture_mm", cam.texture_mm, 1e-3, 1);
    }
    if (const YAML::Node f = s["flicker"]) {
      r_.only_keys(f, "simulation.flicker", {"amplitude", "hz", "drift_hz_per_s"});
      num(f, "amplitude", "simulation.flicker.amplitude", o.camera.flicker_amplitude, 0, 0.99);
      num(f, "hz", "simulation.flicker.hz", o.camera.flicker_hz, 1, 10000);
    }
    if (const YAML::Node m = s["motion"]) {
      r_.only_keys(m, "simulation.motion", {"step_px", "drift_px_per_s", "tremor_px", "tremor_hz", "rotation_deg"});
      num(m, "step_px", "simulation.motion.step_px", o.camera.motion_step_px, 0, 5);
      num(m, "drift_px_per_s", "simulation.motion.drift_px_per_s", o.camera.motion_drift_px_per_s, 0, 100);
      num(m, "tremor_px", "simulation.motion.tremor_px", o.camera.motion_tremor_px, 0, 20);
      num(m, "tremor_hz", "simulation.motion.tremor_hz", o.camera.motion_tremor_hz, 0.1, 100);
      num(m, "rotation_deg", "simulation.motion.rotation_deg", o.camera.motion_rotation_deg, -10, 10);
    }
    if (const YAML::Node b = s["baseline"]) {
      r_.only_keys(b, "simulation.baseline", {"part", "gap_mm"});
      if (auto v = r_.get<std::string>(b, "part", "simulation.baseline.part", "held, absent or touching")) {
        if (*v == "held") o.baseline.part = BaselinePart::held;
        else if (*v == "absent") o.baseline.part = BaselinePart::absent;
        else if (*v == "touching") o.baseline.part = BaselinePart::touching;
        else r_.fail(b["part"], "simulation.baseline.part", "expected held, absent or touching, got '" + *v + "'");
      }
      num(b, "gap_mm", "simulation.baseline.gap_mm", o.baseline.gap_mm, 0, 20);
    }
    if (const YAML::Node m = s["skin_motion"]) {
      r_.only_keys(m, "simulation.skin_motion", {"slide_mm", "bulge_mm", "bulge_width_mm"});
      if (m["slide_mm"]) o.skin_motion.slide_mm = vec2(m["slide_mm"], "simulation.skin_motion.slide_mm");
      if (o.skin_motion.slide_mm.norm() > 5) r_.fail(m["slide_mm"], "simulation.skin_motion.slide_mm", "expected a slide of at most 5 mm");
      num(m, "bulge_mm", "simulation.skin_motion.bulge_mm", o.skin_motion.bulge_mm, -2, 2);
      num(m, "bulge_width_mm", "simulation.skin_motion.bulge_width_mm", o.skin_motion.bulge_width_mm, 0.1, 20);
    }
    if (const YAML::Node p = s["pressure"]) parse_pressure(p, o);
    if (const YAML::Node p = s["presses"]) parse_presses(p, o);
    o.photometric = parse_photometric(r_, s, o.photometric);
  }

 private:
  void num(const YAML::Node& map, const std::string& key, const std::string& full, double& out, double lo, double hi) {
    const auto v = r_.get<double>(map, key, full, "a number");
    if (!v) return;
    if (!std::isfinite(*v) || *v < lo || *v > hi) {
      std::ostringstream m;
      m << "expected a number from " << lo << " to " << hi << ", got " << *v;
      r_.fail(map[key], full, m.str());
    }
    out = *v;
  }
  std::vector<double> numbers(const YAML::Node& n, const std::string& full, std::size_t count) { return r_.numbers(n, full, count); }
  Vec2 vec2(const YAML::Node& n, const std::string& full) {
    const auto v = numbers(n, full, 2);
    return {v[0], v[1]};
  }
  void parse_skin(const YAML::Node& k, SkinParameters& s) {
    const std::string p = "simulation.skin";
    r_.only_keys(k, p, {"tone", "s50_kpa", "width_kpa", "beta", "tau_on_s", "tau_off_s", "pulse_amplitude", "pulse_hz",
                        "k_green", "blur_sigma_mm", "von_mises_weight", "von_mises_depth_mm", "poisson", "ridge_period_mm",
                        "ridge_amplitude", "ridge_warp_mm", "mottling_amplitude", "mottling_scale_mm", "texture_seed"});
    if (auto t = r_.get<std::string>(k, "tone", p + ".tone", "light, medium or dark")) {
      try {
        s.tone = SkinTone::preset(*t);
      } catch (const std::invalid_argument&) {
        r_.fail(k["tone"], p + ".tone", "expected light, medium or dark, got '" + *t + "'");
      }
    }
    num(k, "s50_kpa", p + ".s50_kpa", s.s50_kpa, 0.1, 200);
    num(k, "width_kpa", p + ".width_kpa", s.width_kpa, 0.05, 100);
    num(k, "beta", p + ".beta", s.beta, 1e-4, 1);
    num(k, "tau_on_s", p + ".tau_on_s", s.tau_on_s, 1e-4, 100);
    num(k, "tau_off_s", p + ".tau_off_s", s.tau_off_s, 1e-4, 100);
    num(k, "pulse_amplitude", p + ".pulse_amplitude", s.pulse_amplitude, 0, 0.2);
    num(k, "pulse_hz", p + ".pulse_hz", s.pulse_hz, 0.1, 10);
    double kg = s.absorption[1];
    num(k, "k_green", p + ".k_green", kg, 0, 1);
    s.absorption = Eigen::Vector3d(0.2, 1.0, 0.3) * kg;
    num(k, "blur_sigma_mm", p + ".blur_sigma_mm", s.blur_sigma_mm, 0, SkinBlur::max_sigma_mm);
    num(k, "von_mises_weight", p + ".von_mises_weight", s.von_mises_weight, 0, 1);
    num(k, "von_mises_depth_mm", p + ".von_mises_depth_mm", s.von_mises_depth_mm, 0.01, 5);
    num(k, "poisson", p + ".poisson", s.poisson, 0, 0.499);
    num(k, "ridge_period_mm", p + ".ridge_period_mm", s.ridge_period_mm, 0.05, 2);
    num(k, "ridge_amplitude", p + ".ridge_amplitude", s.ridge_amplitude, 0, 0.4);
    num(k, "ridge_warp_mm", p + ".ridge_warp_mm", s.ridge_warp_mm, 0, 2);
    num(k, "mottling_amplitude", p + ".mottling_amplitude", s.mottling_amplitude, 0, 0.19);
    num(k, "mottling_scale_mm", p + ".mottling_scale_mm", s.mottling_scale_mm, 0.1, 50);
    double ts = s.texture_seed;
    num(k, "texture_seed", p + ".texture_seed", ts, 0, 4294967295.0);
    s.texture_seed = static_cast<std::uint32_t>(ts);
  }
  void parse_pressure(const YAML::Node& p, SimulationSection& o) {
    const std::string pre = "simulation.pressure";
    r_.only_keys(p, pre, {"texel_mm", "map", "sources"});
    num(p, "texel_mm", pre + ".texel_mm", o.field.texel_mm, 0.005, 5);
    o.pressure_map = r_.path(p, "map", pre + ".map");
    if (const YAML::Node list = p["sources"]) {
      if (!list.IsSequence()) r_.fail(list, pre + ".sources", "expected a list of sources");
      for (std::size_t i = 0; i < list.size(); ++i) {
        const YAML::Node n = list[i];
        const std::string q = pre + ".sources[" + std::to_string(i) + "]";
        r_.only_keys(n, q, {"name", "type", "center_uv_mm", "center_part_mm", "peak_kpa", "sigma_mm", "radius_mm", "force_n",
                            "rim_cap_ratio", "sphere_radius_mm", "e_star_kpa"});
        sim::PressureSource s;
        s.name = r_.get<std::string>(n, "name", q + ".name", "a name").value_or("source " + std::to_string(i + 1));
        const std::string type = r_.get<std::string>(n, "type", q + ".type", "gaussian, punch or hertz").value_or("gaussian");
        if (type == "gaussian") s.kind = sim::PressureSource::Kind::gaussian;
        else if (type == "punch") s.kind = sim::PressureSource::Kind::punch;
        else if (type == "hertz") s.kind = sim::PressureSource::Kind::hertz;
        else r_.fail(n["type"], q + ".type", "expected gaussian, punch or hertz, got '" + type + "'");
        if (n["center_uv_mm"]) s.center_uv_mm = vec2(n["center_uv_mm"], q + ".center_uv_mm");
        if (n["center_part_mm"]) {
          const auto v = numbers(n["center_part_mm"], q + ".center_part_mm", 3);
          s.center_part_mm = Vec3(v[0], v[1], v[2]);
        }
        if (s.center_uv_mm.has_value() == s.center_part_mm.has_value())
          r_.fail(n, q, "give exactly one of center_uv_mm (chart, mm) and center_part_mm (part frame, mm)");
        num(n, "peak_kpa", q + ".peak_kpa", s.peak_kpa, 0, 1000);
        num(n, "sigma_mm", q + ".sigma_mm", s.sigma_mm, 0.01, 100);
        num(n, "radius_mm", q + ".radius_mm", s.radius_mm, 0.01, 100);
        num(n, "force_n", q + ".force_n", s.force_n, 0, 1000);
        num(n, "rim_cap_ratio", q + ".rim_cap_ratio", s.rim_cap_ratio, 0.5, 100);
        num(n, "sphere_radius_mm", q + ".sphere_radius_mm", s.sphere_radius_mm, 0.01, 10000);
        num(n, "e_star_kpa", q + ".e_star_kpa", s.e_star_kpa, 0.01, 1e7);
        o.field.sources.push_back(s);
      }
    }
  }
  void parse_presses(const YAML::Node& p, SimulationSection& o) {
    const std::string pre = "simulation.presses";
    r_.only_keys(p, pre, {"diameters_mm", "levels", "max_kpa", "repetitions", "profile", "frames", "px_per_mm", "trial_jitter", "offset_sd", "ring_mm"});
    sim::PressOptions po;
    if (p["diameters_mm"]) po.diameters_mm = numbers(p["diameters_mm"], pre + ".diameters_mm", 0);
    for (double d : po.diameters_mm)
      if (!(d > 0 && d < 50)) r_.fail(p["diameters_mm"], pre + ".diameters_mm", "expected diameters in (0, 50) mm");
    auto whole = [&](const char* key, int& out, int lo, int hi) {
      double v = out;
      num(p, key, pre + "." + key, v, lo, hi);
      if (v != std::floor(v)) r_.fail(p[key], pre + "." + key, "expected a whole number");
      out = static_cast<int>(v);
    };
    whole("levels", po.levels, 2, 100);
    whole("repetitions", po.repetitions, 1, 100);
    whole("frames", po.frames, 1, 100000);
    num(p, "max_kpa", pre + ".max_kpa", po.max_kpa, 0.1, 999);
    num(p, "px_per_mm", pre + ".px_per_mm", po.px_per_mm, 0.1, 1000);
    num(p, "trial_jitter", pre + ".trial_jitter", po.trial_jitter, 0, 0.99);
    num(p, "offset_sd", pre + ".offset_sd", po.offset_sd, 0, 0.99);
    num(p, "ring_mm", pre + ".ring_mm", po.ring_mm, 0, 5);
    if (po.ring_mm > 0 && po.ring_mm < 0.01) r_.fail(p["ring_mm"], pre + ".ring_mm", "expected 0 (no profiles) or a width from 0.01 mm");
    if (auto v = r_.get<std::string>(p, "profile", pre + ".profile", "sneddon or uniform")) {
      if (*v == "sneddon") po.profile = sim::PressOptions::Profile::sneddon;
      else if (*v == "uniform") po.profile = sim::PressOptions::Profile::uniform;
      else r_.fail(p["profile"], pre + ".profile", "expected sneddon or uniform, got '" + *v + "'");
    }
    o.presses = po;
  }
  const SceneReader& r_;
};

}  // namespace

void SimulationSection::read(const YAML::Node& node, const SceneReader& reader) { SimulationParser(reader).parse(node, *this); }

void SimulationSection::validate() const {
  validate_options(skin, camera, timeline, photometric, baseline, skin_motion);
  if (presses) validate_options(*presses);
  if (!(scale >= 0.05 && scale <= 4)) rule_broken("scale", scale, "from 0.05 to 4");
}

}  // namespace clearfit::cli
