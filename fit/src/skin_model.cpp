#include <clearfit/fit/contact_mechanics.hpp>
#include <clearfit/fit/skin_model.hpp>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <numbers>
#include <random>
#include <sstream>
#include <stdexcept>

namespace clearfit {

namespace {
constexpr double kTwoPi = 2 * std::numbers::pi;
double logistic(double x) { return 1 / (1 + std::exp(-x)); }
}  // namespace

double normalized_logistic(double s, double s50, double width) {
  if (!(width > 0)) throw std::invalid_argument("normalized_logistic: width_kpa must be > 0");
  const double l0 = logistic(-s50 / width);
  return (logistic((s - s50) / width) - l0) / (1 - l0);
}

SkinTone SkinTone::preset(const std::string& name) {
  // Green anchored on NIST's forearm range (0.41 / median 0.33 / 0.11); red and blue in the
  // band-mean proportions (R 0.53, B 0.31 at G 0.34), darker skins redder (melanin absorbs blue most).
  if (name == "light") return {name, {0.58, 0.41, 0.36}};
  if (name == "medium") return {name, {0.45, 0.33, 0.27}};
  if (name == "dark") return {name, {0.20, 0.11, 0.08}};
  throw std::invalid_argument("SkinTone::preset: unknown tone '" + name + "' (light, medium, dark)");
}

void SkinParameters::validate() const {
  auto check = [](bool ok, const char* field, double v, const char* rule) {
    if (!ok) {
      std::ostringstream s;
      s << "SkinParameters." << field << " = " << v << ": " << rule;
      throw std::invalid_argument(s.str());
    }
  };
  auto finite = [](double v) { return std::isfinite(v); };
  SkinBlur{blur_sigma_mm}.validate("SkinParameters.blur_sigma_mm");
  check(von_mises_weight >= 0 && von_mises_weight <= 1, "von_mises_weight", von_mises_weight, "must be in [0, 1]");
  check(finite(von_mises_depth_mm) && von_mises_depth_mm > 0, "von_mises_depth_mm", von_mises_depth_mm, "must be > 0");
  check(poisson > -1 && poisson < 0.5, "poisson", poisson, "must be in (-1, 0.5)");
  check(finite(s50_kpa) && s50_kpa > 0, "s50_kpa", s50_kpa, "must be > 0");
  check(finite(width_kpa) && width_kpa > 0, "width_kpa", width_kpa, "must be > 0");
  check(beta > 0 && beta <= 1, "beta", beta, "must be in (0, 1]");
  check(finite(tau_on_s) && tau_on_s > 0, "tau_on_s", tau_on_s, "must be > 0");
  check(finite(tau_off_s) && tau_off_s > 0, "tau_off_s", tau_off_s, "must be > 0");
  check(pulse_amplitude >= 0 && pulse_amplitude < 0.5, "pulse_amplitude", pulse_amplitude, "must be in [0, 0.5)");
  check(finite(pulse_hz) && pulse_hz > 0, "pulse_hz", pulse_hz, "must be > 0");
  for (int c = 0; c < 3; ++c) {
    check(finite(absorption[c]) && absorption[c] >= 0, "absorption", absorption[c], "must be >= 0");
    check(tone.reflectance[c] > 0 && tone.reflectance[c] <= 1, "tone.reflectance", tone.reflectance[c], "must be in (0, 1]");
  }
  check(finite(ridge_period_mm) && ridge_period_mm > 0, "ridge_period_mm", ridge_period_mm, "must be > 0");
  check(ridge_amplitude >= 0 && ridge_amplitude < 0.5, "ridge_amplitude", ridge_amplitude, "must be in [0, 0.5)");
  check(finite(ridge_warp_mm) && ridge_warp_mm >= 0, "ridge_warp_mm", ridge_warp_mm, "must be >= 0");
  check(mottling_amplitude >= 0 && mottling_amplitude < 0.2, "mottling_amplitude", mottling_amplitude, "must be in [0, 0.2)");
  check(finite(mottling_scale_mm) && mottling_scale_mm > 0, "mottling_scale_mm", mottling_scale_mm, "must be > 0");
}

EquivalentCalibration equivalent_calibration(const SkinParameters& p) {
  return {p.absorption[1] * p.beta, p.s50_kpa, p.width_kpa};
}

double steady_blood_loss(const SkinParameters& p, double drive_kpa) {
  return p.beta * normalized_logistic(std::max(drive_kpa, 0.0), p.s50_kpa, p.width_kpa);
}

double lag_step(const SkinParameters& p, double b0, double b_ss, double dt_s) {
  const double tau = b_ss > b0 ? p.tau_on_s : p.tau_off_s;
  return b_ss + (b0 - b_ss) * std::exp(-dt_s / tau);
}

double pulse_waveform(double t_s, double hz) {
  auto raw = [](double ph) { return std::sin(kTwoPi * ph) + 0.4 * std::sin(2 * kTwoPi * ph + 0.6); };
  static const double peak = [&] {
    double m = 0;
    for (int i = 0; i < 4096; ++i) m = std::max(m, std::abs(raw(i / 4096.0)));
    return m;
  }();
  return raw(t_s * hz) / peak;
}

Eigen::Vector3d radiance_factor(const SkinParameters& p, double blood_loss, double pulse) {
  const double b = (1 - blood_loss) * (1 + p.pulse_amplitude * pulse);
  return (-(b - 1) * p.absorption.array()).exp();
}

SkinTexture::SkinTexture(const SkinParameters& p) : p_(p) {
  std::mt19937 rng(p.texture_seed);
  std::uniform_real_distribution<double> u(0, 1);
  const double angle = kTwoPi * u(rng);
  ridge_dir_ = Vec2(std::cos(angle), std::sin(angle));
  const double ph1 = kTwoPi * u(rng), ph2 = kTwoPi * u(rng);
  // Warp: along the ridges (4 mm waviness) and a weaker, slower one across them.
  const Vec2 along(-ridge_dir_.y(), ridge_dir_.x());
  warp_ = {{kTwoPi / 4.0 * along, ph1, p.ridge_warp_mm}, {kTwoPi / 9.0 * ridge_dir_, ph2, 0.2 * p.ridge_warp_mm}};
  constexpr int kWaves = 16;
  for (int i = 0; i < kWaves; ++i) {
    const double lambda = p.mottling_scale_mm * std::exp(std::log(0.5) + u(rng) * std::log(4.0));  // 0.5–2× scale
    const double dir = kTwoPi * u(rng);
    mottle_.push_back({kTwoPi / lambda * Vec2(std::cos(dir), std::sin(dir)), kTwoPi * u(rng), std::sqrt(2.0 / kWaves)});
  }
}

double SkinTexture::ridge(const Vec2& uv) const {
  double phase = uv.dot(ridge_dir_);
  for (const Wave& w : warp_) phase += w.amp * std::sin(w.k.dot(uv) + w.phase);
  return std::cos(kTwoPi * phase / p_.ridge_period_mm);
}

double SkinTexture::mottling(const Vec2& uv) const {
  double m = 0;
  for (const Wave& w : mottle_) m += w.amp * std::cos(w.k.dot(uv) + w.phase);
  return m;
}

double SkinTexture::modulation(const Vec2& uv) const {
  return (1 + p_.ridge_amplitude * ridge(uv)) * (1 + p_.mottling_amplitude * mottling(uv));
}

ChartField skin_drive(const SkinParameters& p, const ChartField& pressure) {
  const ChartGrid& g = pressure.grid;
  if (pressure.value.size() != g.size() || g.size() == 0) throw std::invalid_argument("skin_drive: empty or inconsistent field");
  cv::Mat img(g.height, g.width, CV_32F);
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const float v = pressure.value[g.index(i, j)];
      img.at<float>(j, i) = std::isfinite(v) ? v : 0.0f;
    }
  cv::Mat blurred = img;
  if (p.blur_sigma_mm > 0) {
    const double s = p.blur_sigma_mm / g.texel_mm;
    const int k = 2 * static_cast<int>(std::ceil(4 * s)) + 1;
    cv::GaussianBlur(img, blurred, cv::Size(k, k), s, s, cv::BORDER_CONSTANT);
  }
  ChartField out;
  out.grid = g;
  out.value.assign(blurred.begin<float>(), blurred.end<float>());
  if (p.von_mises_weight > 0) {
    ChartField zeroed = pressure;
    for (float& v : zeroed.value)
      if (!std::isfinite(v)) v = 0;
    const ChartField vm = contact::von_mises_at_depth(zeroed, p.von_mises_depth_mm, p.poisson);
    const float w = static_cast<float>(p.von_mises_weight);
    for (std::size_t k = 0; k < out.value.size(); ++k) out.value[k] = (1 - w) * out.value[k] + w * vm.value[k];
  }
  return out;
}

}  // namespace clearfit
