// Photometric effects of real captures for the simulator: glare blobs per
// phase, exposure / white-balance steps and drifts, drifting mains flicker
// (see simulate_photometric.hpp), and their truth files.
#include <clearfit/atomic_file.hpp>
#include <clearfit/fit/simulate_photometric.hpp>

#include <nlohmann/json.hpp>

#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace clearfit::sim {
namespace {

void require(bool ok, const std::string& field, double value, const char* rule) {
  if (!ok) {
    std::ostringstream m;
    m << field << " = " << value << ": " << rule;
    throw std::invalid_argument(m.str());
  }
}

const char* phases_name(GlareBlob::Phases p) {
  switch (p) {
    case GlareBlob::Phases::both: return "both";
    case GlareBlob::Phases::worn: return "worn";
    case GlareBlob::Phases::baseline: return "baseline";
  }
  return "?";
}

/// Sum of the blobs present in a phase, CV_32F linear.
cv::Mat glare_image(const std::vector<GlareBlob>& blobs, bool worn, cv::Size size) {
  cv::Mat out = cv::Mat::zeros(size, CV_32F);
  for (const GlareBlob& b : blobs) {
    if (b.phases != GlareBlob::Phases::both && (b.phases == GlareBlob::Phases::worn) != worn) continue;
    const double cx = b.center.x() * size.width, cy = b.center.y() * size.height, s = b.sigma * size.width;
    const int r = static_cast<int>(std::ceil(5 * s));
    for (int y = std::max(0, static_cast<int>(cy) - r); y < std::min(size.height, static_cast<int>(cy) + r + 1); ++y) {
      float* row = out.ptr<float>(y);
      for (int x = std::max(0, static_cast<int>(cx) - r); x < std::min(size.width, static_cast<int>(cx) + r + 1); ++x)
        row[x] += static_cast<float>(b.peak * std::exp(-((x - cx) * (x - cx) + (y - cy) * (y - cy)) / (2 * s * s)));
    }
  }
  return out;
}

}  // namespace

void GlareBlob::validate() const {
  require(center.allFinite() && center.x() >= -0.5 && center.x() <= 1.5 && center.y() >= -0.5 && center.y() <= 1.5,
          "glare.center", center.x(), "must be finite, relative to the image size (0..1, at most half an image outside)");
  require(sigma > 0 && sigma <= 1, "glare.sigma", sigma, "must be in (0, 1] (relative to the image width)");
  require(peak >= 0 && peak <= 10, "glare.peak", peak, "must be in [0, 10] (linear)");
}

bool PhotometricEffects::any() const {
  return !glare.empty() || !steps.empty() || drift_per_s != std::array<double, 3>{0, 0, 0} || flicker_drift_hz_per_s != 0;
}

void PhotometricEffects::validate() const {
  for (const auto& b : glare) b.validate();
  for (const auto& s : steps) {
    require(std::isfinite(s.t_s) && s.t_s >= 0, "exposure.steps.t_s", s.t_s, "must be >= 0 s");
    for (double g : s.gain) require(std::isfinite(g) && g > 0.1 && g < 10, "exposure.steps.gain", g, "must be in (0.1, 10)");
  }
  for (double d : drift_per_s) require(std::isfinite(d) && std::abs(d) < 1, "exposure.drift_per_s", d, "must be in (-1, 1)");
  require(std::isfinite(flicker_drift_hz_per_s) && std::abs(flicker_drift_hz_per_s) < 100, "flicker.drift_hz_per_s",
          flicker_drift_hz_per_s, "must be in (-100, 100)");
}

PhotometricSchedule::PhotometricSchedule(const PhotometricEffects& effects, const CameraSettings& camera,
                                         const Timeline& timeline, cv::Size image)
    : fx_(effects), cam_(camera), tl_(timeline) {
  fx_.validate();
  glare_baseline_ = glare_image(fx_.glare, false, image);
  glare_worn_ = glare_image(fx_.glare, true, image);
}

FrameLight PhotometricSchedule::frame(int k) const {
  const double t = k / tl_.fps;
  FrameLight light;
  // Mains flicker: phase 2π(f t + ½ f' t²) for a frequency drifting at f' Hz/s.
  const double phase = 2 * std::numbers::pi * (cam_.flicker_hz * t + 0.5 * fx_.flicker_drift_hz_per_s * t * t);
  const double flicker = 1 + cam_.flicker_amplitude * std::sin(phase);
  for (int c = 0; c < 3; ++c) {
    double g = flicker * (1 + fx_.drift_per_s[c] * t);
    for (const GainStep& s : fx_.steps)
      if (t >= s.t_s) g *= s.gain[c];
    light.gain[c] = g;
  }
  const bool worn = k >= tl_.baseline_frames();
  const cv::Mat& glare = worn ? glare_worn_ : glare_baseline_;
  light.glare = fx_.glare.empty() ? nullptr : &glare;
  return light;
}

std::vector<std::string> PhotometricSchedule::write_truth(const std::filesystem::path& dir) const {
  std::vector<std::string> written;
  const int frames = tl_.baseline_frames() + tl_.press_frames();
  write_file_atomically(dir / "truth_gains.csv", [&](std::ostream& out) {
    out << "frame,t_s,phase,gain_r,gain_g,gain_b\n";
    out.precision(9);
    for (int k = 0; k < frames; ++k) {
      const FrameLight l = frame(k);
      out << k << ',' << k / tl_.fps << ',' << (k < tl_.baseline_frames() ? "baseline" : "worn") << ',' << l.gain[0] << ','
          << l.gain[1] << ',' << l.gain[2] << '\n';
    }
  });
  written.emplace_back("truth_gains.csv");
  nlohmann::json blobs = nlohmann::json::array();
  for (const GlareBlob& b : fx_.glare)
    blobs.push_back({{"phases", phases_name(b.phases)}, {"center", {b.center.x(), b.center.y()}}, {"sigma", b.sigma}, {"peak", b.peak}});
  nlohmann::json steps = nlohmann::json::array();
  for (const GainStep& s : fx_.steps) steps.push_back({{"t_s", s.t_s}, {"gain_rgb", s.gain}});
  if (!fx_.glare.empty()) {
    for (const bool worn : {false, true}) {
      const cv::Mat& g = glare(worn);
      const std::string name = worn ? "truth_glare_worn.npy" : "truth_glare_baseline.npy";
      write_npy_float32(dir / name, {static_cast<std::size_t>(g.rows), static_cast<std::size_t>(g.cols)}, g.ptr<float>());
      written.push_back(name);
    }
  }
  const nlohmann::json j = {{"schema", "clearfit.simulation-photometric/1"},
                            {"glare", blobs},
                            {"glare_images", fx_.glare.empty() ? nlohmann::json(nullptr)
                                                                : nlohmann::json{{"baseline", "truth_glare_baseline.npy"},
                                                                                 {"worn", "truth_glare_worn.npy"},
                                                                                 {"unit", "linear, added before the camera's gains"}}},
                            {"gain_steps", steps},
                            {"gain_drift_per_s_rgb", fx_.drift_per_s},
                            {"flicker", {{"amplitude", cam_.flicker_amplitude}, {"hz", cam_.flicker_hz}, {"drift_hz_per_s", fx_.flicker_drift_hz_per_s}}},
                            {"gains", "truth_gains.csv"}};
  write_file_atomically(dir / "truth_photometric.json", j.dump(2) + "\n");
  written.emplace_back("truth_photometric.json");
  return written;
}

}  // namespace clearfit::sim
