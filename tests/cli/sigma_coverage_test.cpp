// The pressure σ checked by simulation: a small slab with two Gaussian pressure sources is filmed
// (`clearfit simulate`), the wearer calibrated from the simulated presses (`calibrate-pressure`) and the
// captures assessed, over several seeds. The 95 % intervals p ± 1.96σ of pressure.npy and
// pressure_sigma.npy must hold the truth (truth_pressure.npy, on the same chart grid) 90–98 % of the time.
// Counted: every texel whose truth lies within the calibration's range (its detection and saturation
// pressures, calibration.json `limits`) and whose estimate has a σ; texels whose truth is in range but whose
// estimate is below detection or saturated have no interval and are counted apart (printed). Nothing else is
// left out: no edge or steep-gradient texels are excluded. Printed apart: the counted texels estimated under the capture's
// detection limit (the places' tails the hysteresis keeps) and the estimates whose truth lies below the calibration's range.
// The hotspots' figures against the truth's places, defined as the report defines its own: the seen texels (finite
// in pressure.npy) whose truth, at the assessment's texel centres, is at or above the lowest threshold, each texel to
// the nearer source; area-weighted centroid in chart mm. The glare mask cuts the 14 kPa place on every seed (0.7–1.0
// mm² unseen on seeds 1–4): over all the truth's texels its centroid lay 0.04–0.13 mm from the report's, over the
// seen ones 0.02–0.08 mm. Every place found has an area and a centroid σ; how often the 95 % intervals of its mean,
// area, peak and centroid hold the truth is printed, and asserted at the bar
// (check_place_figures; the centroid's σ is the rms distance in the plane: 95 % within 1.73σ). The thresholds (6.5
// and 8 kPa) lie above this capture's detection limit (about 5.3 kPa: the held capture's 5σ gate), so that a place's outline is where the pressure crosses the threshold; below the limit the
// outline is where the signal stops being significant, which the σ of the area and centroid do not model (at
// 4.3 kPa both came out 0 and the areas 25 % small).
// CLEARFIT_SIGMA_SEEDS=11,12,... runs other seeds than the test's 1–4 (seeds not tuned on).
#include "cli_support.hpp"
#include "slab_part.hpp"

#include <clearfit/npy.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <sstream>

namespace clearfit::cli_test {
namespace {

struct Figure {
  int n = 0, held = 0;
  double sum_z2 = 0;
};

struct Counts {
  long long texels = 0, inside = 0, censored = 0;  ///< censored: truth in range, estimate below detection or saturated
  /// Printed apart: the counted texels whose estimate is under the capture's detection limit (report.json
  /// pressure.detection_limit_kpa: the places' tails the hysteresis keeps), and the estimates whose truth lies below
  /// the calibration's range (not counted above).
  long long tail = 0, tail_inside = 0, below_range = 0, below_range_inside = 0;
  double sum_z2 = 0, sum_z = 0;
  /// The hotspots' figures (mean, area, centroid, peak): how many had a σ, how many held the truth, Σ z².
  std::map<std::string, Figure> places;
};

/// The sources the scene below renders: centre on the chart (mm).
const std::vector<Vec2> kSources{{8, 9}, {17, 9}};

/// The truth at the assessment's texel centres (interpolated: the truth's grid has its texel centres on whole
/// multiples of the texel, the assessment's half a texel inside the chart), NaN outside the truth's grid.
std::vector<double> truth_on_assessment_grid(const npy::Float32Array& truth, const nlohmann::json& tg, const nlohmann::json& ag,
                                             std::size_t h, std::size_t w) {
  const double t_mm = tg["texel_mm"], a_mm = ag["texel_mm"];
  const long th = static_cast<long>(truth.shape[0]), tw = static_cast<long>(truth.shape[1]);
  auto truth_at = [&](double u, double v) {
    const double fx = (u - tg["uv_origin_mm"][0].get<double>()) / t_mm, fy = (v - tg["uv_origin_mm"][1].get<double>()) / t_mm;
    const long x = static_cast<long>(std::floor(fx)), y = static_cast<long>(std::floor(fy));
    if (x < 0 || y < 0 || x + 1 >= tw || y + 1 >= th) return std::numeric_limits<double>::quiet_NaN();
    const double ax = fx - x, ay = fy - y;
    auto T = [&](long i, long j) { return static_cast<double>(truth.values[j * tw + i]); };
    return (1 - ax) * (1 - ay) * T(x, y) + ax * (1 - ay) * T(x + 1, y) + (1 - ax) * ay * T(x, y + 1) + ax * ay * T(x + 1, y + 1);
  };
  std::vector<double> out(h * w);
  for (std::size_t k = 0; k < out.size(); ++k)
    out[k] = truth_at(ag["uv_min_mm"][0].get<double>() + a_mm * (k % w), ag["uv_min_mm"][1].get<double>() + a_mm * (k / w));
  return out;
}

/// The truth's places at `threshold` (kPa) as the report defines its own (docs/assessment-outputs.md): the seen
/// texels (finite in pressure.npy) whose truth is at or above it, each to the nearer source; area (mm²), mean
/// (kPa), peak (kPa) and area-weighted centroid (chart mm). The skin under the glare mask is not seen: a place
/// it cuts has its figures over the rest (the report says so in a warning and in unseen_area_mm2).
struct TruthPlace {
  double area = 0, sum = 0, peak = 0;
  Vec2 centroid = Vec2::Zero();
};
std::vector<TruthPlace> truth_places(const std::vector<double>& truth, const npy::Float32Array& p, const nlohmann::json& ag,
                                     double threshold) {
  std::vector<TruthPlace> out(kSources.size());
  const double t_mm = ag["texel_mm"];
  const Vec2 origin(ag["uv_min_mm"][0].get<double>(), ag["uv_min_mm"][1].get<double>());
  const std::size_t w = p.shape[1];
  for (std::size_t k = 0; k < truth.size(); ++k) {
    const double v = truth[k];
    if (!(v >= threshold) || !std::isfinite(p.values[k])) continue;
    const Vec2 uv = origin + t_mm * Vec2(static_cast<double>(k % w), static_cast<double>(k / w));
    const std::size_t s = (uv - kSources[0]).norm() < (uv - kSources[1]).norm() ? 0 : 1;
    out[s].area += t_mm * t_mm, out[s].sum += v * t_mm * t_mm, out[s].peak = std::max(out[s].peak, v);
    out[s].centroid += t_mm * t_mm * uv;
  }
  for (auto& pl : out)
    if (pl.area > 0) pl.centroid /= pl.area, pl.sum /= pl.area;
  return out;
}

/// The report's places against the truth's: each figure with a σ counted, and whether its 95 % interval holds the truth.
void check_places(const nlohmann::json& report, const std::vector<double>& truth, const npy::Float32Array& p, int seed, Counts& c) {
  const double threshold = report["thresholds_kpa"][0];
  const auto places = truth_places(truth, p, report["chart"], threshold);
  for (std::size_t s = 0; s < kSources.size(); ++s) {
    const nlohmann::json* best = nullptr;
    double best_d = 1e9;
    for (const auto& h : report["hotspots"]) {
      const double d = (Vec2(h["centroid_uv_mm"][0].get<double>(), h["centroid_uv_mm"][1].get<double>()) - places[s].centroid).norm();
      if (d < best_d) best_d = d, best = &h;
    }
    if (!best || best_d > 2) {
      ADD_FAILURE() << "seed " << seed << ", source " << s << ": no place found near the truth's";
      continue;
    }
    const auto& h = *best;
    auto count = [&](const std::string& what, double estimate, double sigma, double truth_value, double bound) {
      if (!std::isfinite(sigma) || !(sigma > 0)) {
        std::printf("  seed %d, source %zu, %s %.3f (truth %.3f): no sigma\n", seed, s, what.c_str(), estimate, truth_value);
        return;
      }
      const double z = (estimate - truth_value) / sigma;
      std::printf("  seed %d, source %zu, %s %.3f +- %.3f (truth %.3f): z %+.2f\n", seed, s, what.c_str(), estimate, sigma, truth_value, z);
      Figure& f = c.places[what];
      f.n += 1, f.held += std::abs(z) <= bound, f.sum_z2 += z * z;
    };
    auto number = [](const nlohmann::json& j) { return j.is_number() ? j.get<double>() : std::numeric_limits<double>::quiet_NaN(); };
    count("mean", number(h["mean_kpa"]), number(h["mean_sigma_kpa"]), places[s].sum, 1.96);
    count("area", number(h["area_mm2"]), number(h["levels"][0]["area_sigma_mm2"]), places[s].area, 1.96);
    count("peak", number(h["peak_kpa"]), number(h["peak_sigma_kpa"]), places[s].peak, 1.96);
    count("centroid", best_d, number(h["centroid_sigma_mm"]), 0.0, std::sqrt(5.991 / 2));
    EXPECT_GT(number(h["levels"][0]["area_sigma_mm2"]), 0) << "seed " << seed << ", source " << s;
    EXPECT_GT(number(h["centroid_sigma_mm"]), 0) << "seed " << seed << ", source " << s;
  }
}

/// One seed: simulate, calibrate, assess in `dir`; the texels with an estimate against the truth.
Counts run_seed(const fs::path& dir, int seed) {
  fs::create_directories(dir);
  write_slab_part(dir);
  write_text(dir / "sim.yaml", "mesh: slab.obj\nior: 1.49\ncontact: {group: contact}\ncamera: cam.cameramodel\n"
                               "simulation:\n  seed: " + std::to_string(seed) + "\n  format: huffyuv\n"
                               "  timeline: {fps: 30, baseline_s: 2, press_s: 2.5}\n  skin: {tone: medium}\n"
                               "  pressure:\n    texel_mm: 0.1\n    sources:\n"
                               "      - {name: a, type: gaussian, center_uv_mm: [8, 9], peak_kpa: 14, sigma_mm: 2.5}\n"
                               "      - {name: b, type: gaussian, center_uv_mm: [17, 9], peak_kpa: 10, sigma_mm: 1.5}\n"
                               "  presses: {diameters_mm: [3], levels: 9, repetitions: 3}\n");
  write_text(dir / "scene.yaml", "mesh: slab.obj\nior: 1.49\ncontact: {group: contact}\ncamera: cam.cameramodel\n"
                                 "outputs: {folder: out, texel_mm: 0.1}\n"
                                 "captures: {baseline: captures/baseline.mkv, worn: captures/worn.mkv, window_frames: 40}\n"
                                 "calibration: {pressure: captures/calibration.json, person: wearer-1}\n"
                                 "assess: {thresholds_kpa: [6.5, 8]}\n");
  const RunResult sim = run_clearfit({"simulate", "sim.yaml", "--out", "captures", "--quiet", "--no-cache"}, dir, dir, 120);
  if (sim.exit_code != 0) throw std::runtime_error("simulate failed:\n" + sim.err);
  const RunResult cal = run_clearfit({"calibrate-pressure", "--presses", "captures/presses.csv", "--person", "wearer-1", "--camera",
                                      "cam.cameramodel", "--out", "captures/calibration.json"},
                                     dir, dir, 60);
  if (cal.exit_code != 0) throw std::runtime_error("calibrate-pressure failed:\n" + cal.err);
  const RunResult as = run_clearfit({"assess", "scene.yaml", "--quiet", "--no-cache", "--no-html"}, dir, dir, 120);
  if (as.exit_code != 0) throw std::runtime_error("assess failed:\n" + as.err);
  const npy::Float32Array truth = npy::read_float32(dir / "captures" / "truth_pressure.npy");
  const npy::Float32Array p = npy::read_float32(dir / "out" / "pressure.npy");
  const npy::Float32Array s = npy::read_float32(dir / "out" / "pressure_sigma.npy");
  if (s.shape != p.shape || p.shape.size() != 2 || truth.shape.size() != 2) throw std::runtime_error("unexpected array shapes");
  const auto tg = nlohmann::json::parse(read_text(dir / "captures" / "truth.json"))["chart_grid"];
  const auto report = nlohmann::json::parse(read_text(dir / "out" / "report.json"));
  const auto limits = nlohmann::json::parse(read_text(dir / "captures" / "calibration.json"))["limits"];
  const double p_lo = limits["detection_kpa"], p_hi = limits["saturation_kpa"];
  const std::vector<double> truth_a = truth_on_assessment_grid(truth, tg, report["chart"], p.shape[0], p.shape[1]);
  Counts c;
  const double tail_below = report["pressure"]["detection_limit_kpa"];
  for (std::size_t k = 0; k < p.values.size(); ++k) {
    const double t = truth_a[k];
    // The truth within the calibration's range (between its detection and saturation pressures), the estimate with a σ.
    if (t < p_lo && std::isfinite(s.values[k])) ++c.below_range, c.below_range_inside += std::abs(p.values[k] - t) <= 1.96 * s.values[k];
    if (!(t >= p_lo && t <= p_hi)) continue;
    if (!std::isfinite(s.values[k])) {
      ++c.censored;
      continue;
    }
    const double z = (p.values[k] - t) / s.values[k];
    ++c.texels;
    c.inside += std::abs(z) <= 1.96;
    if (p.values[k] < tail_below) ++c.tail, c.tail_inside += std::abs(z) <= 1.96;
    c.sum_z2 += z * z;
    c.sum_z += z;
  }
  check_places(report, truth_a, p, seed, c);
  return c;
}

/// P(X ≤ k), X ~ Binomial(n, p).
double binomial_cdf(int k, int n, double p) {
  double sum = 0;
  for (int i = 0; i <= std::min(k, n); ++i)
    sum += std::exp(std::lgamma(n + 1.0) - std::lgamma(i + 1.0) - std::lgamma(n - i + 1.0) + i * std::log(p) + (n - i) * std::log1p(-p));
  return sum;
}

/// P(X ≤ x), X ~ Gamma(n, 1) with n whole: the sum of n values d²/σ² of a centroid whose error is a plane Gaussian
/// of rms distance σ (each an exponential of mean 1).
double gamma_cdf(int n, double x) {
  double term = 1, sum = 1;
  for (int k = 1; k < n; ++k) term *= x / k, sum += term;
  return 1 - std::exp(-x) * sum;
}

/// The places' figures at the bar: a count of intervals holding the truth that a coverage between 90 and 98 %
/// gives with a chance of at least 2.5 % on either side (with a dozen places the count cannot say more: 7 of 8 is
/// 87.5 % and comes from a true 95 % a third of the time). The centroid's distances also against their σ: Σ d²/σ²
/// within the central 98 % of its law, which the counts alone cannot do with 8 places: on seeds 1–4, with the truth
/// over all its texels and the outline fit settling on one edge of the slab (0.17 px off), 5 of 8 held and Σ d²/σ²
/// was 32.3 (P 1e-7); over the seen texels 7 of 8 and 11.2 (P 0.13); with the fit's stretch 8 of 8 and 7.3. The mean
/// (the 10 kPa place's: the 14 kPa place is saturated, its mean has no σ) read 0.2–0.4 kPa low with the deblur's
/// smoothed Laplacian, 0.0–0.3 kPa with its difference of Gaussians (README, kPa ± σ: noise-free, half of what is left
/// is the logistic's curvature, the skin's blur acting before it, half the deblur's own shortfall); its σ counts the model's residual (what the
/// deblur and the logistic's curvature leave, pressure_sigma_parts) as one error over the place, not as noise averaged down: rms z 0.95 over
/// seeds 1–4, 11–16, 21–26, 31–34 (0.51 when the blur's whole first-order term stood in for it).
void check_place_figures(const std::map<std::string, Figure>& places) {
  for (const auto& [what, f] : places) {
    const double low = binomial_cdf(f.held, f.n, 0.90), high = 1 - binomial_cdf(f.held - 1, f.n, 0.98);
    std::printf("hotspot %s: the 95 %% interval holds the truth %d of %d times (rms z %.2f; P(so few | 90 %%) %.3f, P(so many | 98 %%) %.3f)\n",
                what.c_str(), f.held, f.n, std::sqrt(f.sum_z2 / std::max(1, f.n)), low, high);
    if (f.n == 0) continue;
    EXPECT_GE(low, 0.025) << what << ": " << f.held << " of " << f.n;
    EXPECT_GE(high, 0.025) << what << ": " << f.held << " of " << f.n;
    if (what != "centroid") continue;
    const double p = gamma_cdf(f.n, f.sum_z2);
    std::printf("hotspot centroid: sum of (d / sigma)^2 %.2f over %d places, P(less) %.3f\n", f.sum_z2, f.n, p);
    EXPECT_GE(p, 0.01);
    EXPECT_LE(p, 0.99);
  }
}

TEST(SigmaCoverage, NinetyFivePercentIntervalsHoldTheTruth) {
  const fs::path root = fs::temp_directory_path() / ("clearfit_sigma_coverage_" + std::to_string(::getpid()));
  fs::remove_all(root);
  Counts all;
  std::vector<int> seeds{1, 2, 3, 4};
  if (const char* list = std::getenv("CLEARFIT_SIGMA_SEEDS")) {
    seeds.clear();
    std::stringstream s(list);
    for (std::string item; std::getline(s, item, ',');) seeds.push_back(std::stoi(item));
  }
  for (int seed : seeds) {
    const Counts c = run_seed(root / std::to_string(seed), seed);
    std::printf("seed %d: %lld texels (truth in the calibration's range, with an estimate; %lld more below detection or "
                "saturated), %.1f %% inside p ± 1.96σ, mean z %+.2f, rms z %.2f\n",
                seed, c.texels, c.censored, 100.0 * c.inside / std::max(1LL, c.texels), c.sum_z / std::max(1LL, c.texels),
                std::sqrt(c.sum_z2 / std::max(1LL, c.texels)));
    EXPECT_GT(c.texels, 500) << "seed " << seed;
    all.texels += c.texels, all.inside += c.inside, all.sum_z2 += c.sum_z2, all.sum_z += c.sum_z;
    all.tail += c.tail, all.tail_inside += c.tail_inside, all.below_range += c.below_range, all.below_range_inside += c.below_range_inside;
    for (const auto& [what, f] : c.places) {
      Figure& a = all.places[what];
      a.n += f.n, a.held += f.held, a.sum_z2 += f.sum_z2;
    }
  }
  check_place_figures(all.places);
  std::printf("of them estimated under the capture's detection limit (the places' tails): %.1f %% of %lld; estimates whose truth is below "
              "the calibration's range (not counted): %.1f %% of %lld inside p ± 1.96σ\n",
              100.0 * all.tail_inside / std::max(1LL, all.tail), all.tail, 100.0 * all.below_range_inside / std::max(1LL, all.below_range),
              all.below_range);
  const double coverage = static_cast<double>(all.inside) / all.texels;
  std::printf("coverage of the 95 %% intervals: %.1f %% of %lld texels over %zu seeds (mean z %+.2f, rms z %.2f)\n", 100 * coverage,
              all.texels, seeds.size(), all.sum_z / all.texels, std::sqrt(all.sum_z2 / all.texels));
  EXPECT_GE(coverage, 0.90);
  EXPECT_LE(coverage, 0.98);
  if (!HasFailure() && std::getenv("CLEARFIT_KEEP_TEST_OUTPUT") == nullptr) fs::remove_all(root);
}

}  // namespace
}  // namespace clearfit::cli_test
