// The scene file's photometric effects for `clearfit simulate`:
//   simulation:
//     glare:                        # specular highlights on the part (white light added)
//       - {center: [0.45, 0.5], sigma: 0.03, peak: 0.3, phases: both}   # both | worn | baseline
//     exposure:                     # the camera's gains (exposure × white balance), R, G, B
//       steps: [{t_s: 1.0, gain: [1.05, 1.05, 1.05]}, {t_s: 3.0, gain: [0.97, 1.0, 1.04]}]
//       drift_per_s: [0.01, 0.0, -0.01]
//     flicker: {amplitude: 0.05, hz: 100, drift_hz_per_s: 0.2}
#include <clearfit/cli/simulate_photometric.hpp>

#include <cmath>
#include <sstream>

namespace clearfit::cli {
namespace {

double number(const SceneReader& r, const YAML::Node& n, const std::string& full, double lo, double hi) {
  double v = 0;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    r.fail(n, full, "expected a number, got '" + (n.IsScalar() ? n.Scalar() : std::string("a list or map")) + "'");
  }
  if (!std::isfinite(v) || v < lo || v > hi) {
    std::ostringstream m;
    m << "expected a number from " << lo << " to " << hi << ", got " << v;
    r.fail(n, full, m.str());
  }
  return v;
}

std::vector<double> numbers(const SceneReader& r, const YAML::Node& n, const std::string& full, std::size_t count, double lo,
                            double hi) {
  if (!n.IsSequence() || n.size() != count) r.fail(n, full, "expected a list of " + std::to_string(count) + " numbers");
  std::vector<double> v;
  for (const auto& e : n) v.push_back(number(r, e, full, lo, hi));
  return v;
}

std::array<double, 3> rgb(const SceneReader& r, const YAML::Node& n, const std::string& full, double lo, double hi) {
  const auto v = numbers(r, n, full, 3, lo, hi);
  return {v[0], v[1], v[2]};
}

}  // namespace

sim::PhotometricEffects parse_photometric(const SceneReader& r, const YAML::Node& simulation, sim::PhotometricEffects fx) {
  if (const YAML::Node list = simulation["glare"]) {
    if (!list.IsSequence()) r.fail(list, "simulation.glare", "expected a list of glare blobs");
    fx.glare.clear();
    for (std::size_t i = 0; i < list.size(); ++i) {
      const YAML::Node n = list[i];
      const std::string p = "simulation.glare[" + std::to_string(i) + "]";
      r.only_keys(n, p, {"center", "sigma", "peak", "phases"});
      sim::GlareBlob b;
      if (n["center"]) {
        const auto c = numbers(r, n["center"], p + ".center", 2, -0.5, 1.5);
        b.center = Vec2(c[0], c[1]);
      }
      if (n["sigma"]) b.sigma = number(r, n["sigma"], p + ".sigma", 1e-4, 1);
      if (n["peak"]) b.peak = number(r, n["peak"], p + ".peak", 0, 10);
      if (auto v = r.get<std::string>(n, "phases", p + ".phases", "both, worn or baseline")) {
        if (*v == "both") b.phases = sim::GlareBlob::Phases::both;
        else if (*v == "worn") b.phases = sim::GlareBlob::Phases::worn;
        else if (*v == "baseline") b.phases = sim::GlareBlob::Phases::baseline;
        else r.fail(n["phases"], p + ".phases", "expected both, worn or baseline, got '" + *v + "'");
      }
      fx.glare.push_back(b);
    }
  }
  if (const YAML::Node e = simulation["exposure"]) {
    r.only_keys(e, "simulation.exposure", {"steps", "drift_per_s"});
    if (const YAML::Node steps = e["steps"]) {
      if (!steps.IsSequence()) r.fail(steps, "simulation.exposure.steps", "expected a list of {t_s, gain}");
      fx.steps.clear();
      for (std::size_t i = 0; i < steps.size(); ++i) {
        const std::string p = "simulation.exposure.steps[" + std::to_string(i) + "]";
        r.only_keys(steps[i], p, {"t_s", "gain"});
        if (!steps[i]["t_s"] || !steps[i]["gain"]) r.fail(steps[i], p, "expected both t_s (seconds) and gain");
        sim::GainStep s;
        s.t_s = number(r, steps[i]["t_s"], p + ".t_s", 0, 1e5);
        const YAML::Node g = steps[i]["gain"];
        if (g.IsScalar()) s.gain.fill(number(r, g, p + ".gain", 0.11, 9.9));
        else s.gain = rgb(r, g, p + ".gain", 0.11, 9.9);
        fx.steps.push_back(s);
      }
    }
    if (e["drift_per_s"]) fx.drift_per_s = rgb(r, e["drift_per_s"], "simulation.exposure.drift_per_s", -0.99, 0.99);
  }
  if (const YAML::Node f = simulation["flicker"]; f && f.IsMap() && f["drift_hz_per_s"])
    fx.flicker_drift_hz_per_s = number(r, f["drift_hz_per_s"], "simulation.flicker.drift_hz_per_s", -99, 99);
  return fx;
}

}  // namespace clearfit::cli
