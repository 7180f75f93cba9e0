// The gauge's clock against the video's (force_log.hpp): a coarse correlation
// search over offsets, then a least-squares fit of offset and drift to the
// press onsets and releases seen in both traces.
#include <clearfit/error.hpp>
#include <clearfit/fit/force_log.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace clearfit {
namespace {

/// The force's expected image signal on a uniform gauge-time grid: the normalised force through a
/// first-order lag (τ_on rising, τ_off falling), as blanching follows pressure (SKIN.md).
struct Response {
  double t0 = 0, dt = 0.01;
  std::vector<double> r;
  double at(double t) const {
    const double x = (t - t0) / dt;
    if (x < 0 || x > double(r.size() - 1)) return NAN;
    const auto i = std::min(static_cast<std::size_t>(x), r.size() - 2);
    return r[i] + (x - double(i)) * (r[i + 1] - r[i]);
  }
};

Response response(const ForceLog& log, const AlignmentOptions& o) {
  Response out;
  out.t0 = log.time_s.front();
  const double top = std::max(1e-12, *std::max_element(log.force_n.begin(), log.force_n.end()));
  const auto n = static_cast<std::size_t>((log.time_s.back() - out.t0) / out.dt) + 1;
  out.r.resize(n);
  double state = 0;
  std::size_t j = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = out.t0 + double(i) * out.dt;
    while (j + 2 < log.time_s.size() && log.time_s[j + 1] < t) ++j;
    const double w = std::clamp((t - log.time_s[j]) / (log.time_s[j + 1] - log.time_s[j]), 0.0, 1.0);
    const double u = std::max(0.0, (log.force_n[j] + w * (log.force_n[j + 1] - log.force_n[j])) / top);
    state += (u - state) * (1 - std::exp(-out.dt / (u > state ? o.tau_on_s : o.tau_off_s)));
    out.r[i] = state;
  }
  return out;
}

/// Pearson correlation of the observed signal with the response at the mapped times (NaN if < half overlaps).
double correlation(const Response& resp, const std::vector<double>& tv, const std::vector<double>& s, double offset,
                   double drift) {
  double n = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  for (std::size_t i = 0; i < tv.size(); ++i) {
    const double p = resp.at((1 + drift) * tv[i] + offset);
    if (std::isnan(p)) continue;
    n += 1, sx += p, sy += s[i], sxx += p * p, syy += s[i] * s[i], sxy += p * s[i];
  }
  if (n < 0.5 * double(tv.size())) return NAN;
  const double cov = sxy - sx * sy / n, vx = sxx - sx * sx / n, vy = syy - sy * sy / n;
  return vx > 0 && vy > 0 ? cov / std::sqrt(vx * vy) : NAN;
}

/// First crossing of `level` (upward if `up`) by the series after time `from`, interpolated; NaN if none before `to`.
double crossing(const std::vector<double>& t, const std::vector<double>& v, double level, bool up, double from, double to) {
  for (std::size_t i = 1; i < t.size(); ++i) {
    if (t[i] < from) continue;
    if (t[i - 1] > to) break;
    const bool before = up ? v[i - 1] < level : v[i - 1] > level, after = up ? v[i] >= level : v[i] <= level;
    if (before && after) return t[i - 1] + (level - v[i - 1]) / (v[i] - v[i - 1]) * (t[i] - t[i - 1]);
  }
  return NAN;
}

double median_between(const std::vector<double>& t, const std::vector<double>& v, double a, double b) {
  std::vector<double> w;
  for (std::size_t i = 0; i < t.size(); ++i)
    if (t[i] >= a && t[i] <= b) w.push_back(v[i]);
  if (w.empty()) return NAN;
  std::nth_element(w.begin(), w.begin() + static_cast<std::ptrdiff_t>(w.size() / 2), w.end());
  return w[w.size() / 2];
}

struct Event {
  double video_s, gauge_s;
  bool release;
};

/// Onset and release times of each press: observed (video clock) against predicted (gauge clock).
std::vector<Event> match_events(const Response& resp, const std::vector<ForcePress>& presses,
                                                    const std::vector<double>& tv, const std::vector<double>& s,
                                                    const ClockAlignment& a, double noise) {
  std::vector<double> tg(resp.r.size());
  for (std::size_t i = 0; i < tg.size(); ++i) tg[i] = resp.t0 + double(i) * resp.dt;
  std::vector<Event> events;
  for (const ForcePress& p : presses) {
    const double rest = median_between(tv, s, a.to_video(p.rest_start_s), a.to_video(p.rest_end_s));
    const double hold = median_between(tv, s, a.to_video(p.hold_start_s), a.to_video(p.hold_end_s));
    if (!(hold - rest > 5 * noise)) continue;  // too faint an edge to time
    const double pr = resp.at(p.rest_end_s), ph = resp.at(p.hold_end_s);
    for (const bool up : {true, false}) {
      const double g_from = (up ? p.start_s : p.end_s) - 1.0;
      const double g = crossing(tg, resp.r, 0.5 * (pr + ph), up, g_from, g_from + 6);
      const double v = crossing(tv, s, 0.5 * (rest + hold), up, a.to_video(g_from) - 1.0, a.to_video(g_from) + 7);
      if (std::isfinite(g) && std::isfinite(v)) events.push_back({v, g, !up});
    }
  }
  return events;
}

}  // namespace

void AlignmentOptions::validate() const {
  auto need = [](bool ok, const char* field, double v, const char* rule) {
    if (!ok) throw std::invalid_argument(std::string(field) + " = " + std::to_string(v) + ": " + rule);
  };
  need(max_offset_s > 0, "max_offset_s", max_offset_s, "must be positive");
  need(max_drift >= 0 && max_drift < 0.1, "max_drift", max_drift, "must be in [0, 0.1)");
  need(tau_on_s > 0 && tau_off_s > 0, "tau_on_s", tau_on_s, "time constants must be positive");
  need(ambiguity > 0 && ambiguity < 1, "ambiguity", ambiguity, "must be in (0, 1)");
}

ClockAlignment align_clocks(const ForceLog& log, const std::vector<ForcePress>& presses, const std::vector<double>& tv,
                            const std::vector<double>& signal, const AlignmentOptions& o) {
  o.validate();
  const std::string file = log.source.string();
  if (presses.size() < 3)
    throw InputError(file, "", "holds " + std::to_string(presses.size()) + " presses; at least 3 are needed to align its clock",
                     "record a session with more presses");
  if (tv.size() != signal.size() || tv.size() < 20) throw std::invalid_argument("align_clocks: video times and signal differ or are too few");
  const Response resp = response(log, o);
  ClockAlignment a;
  // Coarse: offsets every 50 ms at zero drift; the best and the best peak more than 3 s away.
  std::vector<std::pair<double, double>> scan;
  for (double off = -o.max_offset_s; off <= o.max_offset_s; off += 0.05) scan.emplace_back(off, correlation(resp, tv, signal, off, 0));
  double best = -2, second = -2;
  for (const auto& [off, c] : scan)
    if (c > best) best = c, a.offset_s = off;
  for (const auto& [off, c] : scan)
    if (std::abs(off - a.offset_s) > 3 && c > second) second = c;
  a.second_peak_ratio = best > 0 ? std::max(0.0, second) / best : 1;
  if (!(best > 0.3) || a.second_peak_ratio >= o.ambiguity)
    throw InputError(file, "clock", "cannot be aligned to the video unambiguously (best correlation " + std::to_string(best) +
                                        ", next peak " + std::to_string(a.second_peak_ratio * 100) + " % of it)",
                     "vary the force or the rest between presses, or record more presses");
  // Fine: least squares of gauge event times on video event times, with one drift and an intercept of
  // its own for the releases (a person's refill is slower or faster than the model's: that shifts the
  // releases, not the clock); the offset is the onsets' intercept. Three rounds: events re-found each time.
  std::vector<double> diffs;
  for (std::size_t i = 1; i < signal.size(); ++i) diffs.push_back(std::abs(signal[i] - signal[i - 1]));
  std::nth_element(diffs.begin(), diffs.begin() + static_cast<std::ptrdiff_t>(diffs.size() / 2), diffs.end());
  const double noise = 1.4826 * diffs[diffs.size() / 2] / std::sqrt(2.0);
  for (int round = 0; round < 3; ++round) {
    const auto events = match_events(resp, presses, tv, signal, a, noise);
    a.events = static_cast<int>(events.size());
    if (events.size() < 3)
      throw InputError(file, "clock", "only " + std::to_string(events.size()) + " press onsets or releases show in the video",
                       "check that the indenter area is the one pressed and the presses blanch the skin");
    Eigen::MatrixXd x(events.size(), 3);
    Eigen::VectorXd y(events.size());
    for (std::size_t k = 0; k < events.size(); ++k) {
      x.row(k) << events[k].video_s, 1, events[k].release ? 1 : 0;
      y[k] = events[k].gauge_s;
    }
    const Eigen::Vector3d beta = x.colPivHouseholderQr().solve(y);
    const double dof = std::max<double>(1, double(events.size()) - 3);
    const Eigen::Matrix3d cov = (y - x * beta).squaredNorm() / dof * (x.transpose() * x).inverse();
    a.drift = beta[0] - 1;
    a.offset_s = beta[1];
    a.drift_sigma = std::sqrt(cov(0, 0));
    a.offset_sigma_s = std::sqrt(cov(1, 1));
  }
  if (std::abs(a.drift) > o.max_drift)
    throw InputError(file, "clock", "drifts by " + std::to_string(a.drift * 1e6) + " ppm against the video, beyond the " +
                                        std::to_string(o.max_drift * 1e6) + " ppm allowed",
                     "check the log's time unit and that it belongs to this recording");
  a.correlation = correlation(resp, tv, signal, a.offset_s, a.drift);
  a.lag_s = o.tau_on_s * std::log(2.0);  // the response model's half-rise delay behind a force step
  return a;
}

}  // namespace clearfit
