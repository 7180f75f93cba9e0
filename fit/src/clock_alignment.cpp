// The gauge's clock against the video's (force_log.hpp): a coarse correlation
// search over offsets, a least-squares fit of offset and drift to the press
// onsets and releases seen in both traces, then a fit of the whole trace around
// every press (offset, drift and the blanching's two time constants; each press
// its own rest level and amplitude, which absorb the skin's nonlinear response
// to the press's force).
#include <clearfit/error.hpp>
#include <clearfit/fit/force_log.hpp>

#include <Eigen/Dense>
#include <unsupported/Eigen/NonLinearOptimization>
#include <unsupported/Eigen/NumericalDiff>

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

/// The force's normalised steady response `steady(u)` (u the force over the log's largest) through a
/// first-order lag, τ_on rising and τ_off falling, on a uniform gauge-time grid.
template <class Steady>
Response lagged_response(const ForceLog& log, Steady steady, double tau_on, double tau_off) {
  Response out;
  out.t0 = log.time_s.front();
  const double top = std::max(1e-12, *std::max_element(log.force_n.begin(), log.force_n.end()));
  const auto n = static_cast<std::size_t>((log.time_s.back() - out.t0) / out.dt) + 1;
  out.r.resize(n);
  double state = 0;
  std::size_t j = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = out.t0 + (double(i) - 0.5) * out.dt;  // the force over the step before the sample, at its middle
    while (j + 2 < log.time_s.size() && log.time_s[j + 1] < t) ++j;
    const double w = std::clamp((t - log.time_s[j]) / (log.time_s[j + 1] - log.time_s[j]), 0.0, 1.0);
    const double target = steady(std::max(0.0, (log.force_n[j] + w * (log.force_n[j + 1] - log.force_n[j])) / top));
    state += (target - state) * (1 - std::exp(-out.dt / (target > state ? tau_on : tau_off)));
    out.r[i] = state;
  }
  return out;
}

Response response(const ForceLog& log, const AlignmentOptions& o) {
  return lagged_response(log, [](double u) { return u; }, o.tau_on_s, o.tau_off_s);
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

/// The whole-trace model: the blanching B follows the force's steady response L(u) (u the force over the log's
/// largest, L a normalised logistic: blanching is a sigmoid of pressure, so a strong press starts blanching early
/// in its ramp and a weak one late) through a first-order lag (τ_on rising, τ_off falling); around press k
/// (video samples window[k]) signal = rest_k + A·B(gauge time). x = (offset, drift·1e3, ln τ_on, ln τ_off, u50,
/// ln u_w); rest_k and A are solved linearly for every x (variable projection).
Response trace_response(const ForceLog& log, const Eigen::VectorXd& x) {
  const double tau_on = std::exp(std::clamp(x[2], -5.0, 3.0)), tau_off = std::exp(std::clamp(x[3], -5.0, 3.0));
  const double u50 = x[4], uw = std::exp(std::clamp(x[5], -6.0, 3.0));
  auto sig = [](double z) { return 1 / (1 + std::exp(-z)); };
  const double s0 = sig(-u50 / uw);
  return lagged_response(log, [&](double u) { return (sig((u - u50) / uw) - s0) / (1 - s0); }, tau_on, tau_off);
}

struct TraceResiduals {
  using Scalar = double;
  enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };
  using InputType = Eigen::VectorXd;
  using ValueType = Eigen::VectorXd;
  using JacobianType = Eigen::MatrixXd;
  const ForceLog* log;
  const std::vector<double>* tv;
  const std::vector<double>* s;
  std::vector<std::vector<std::size_t>> windows;
  int inputs() const { return 6; }
  int values() const {
    int n = 0;
    for (const auto& w : windows) n += static_cast<int>(w.size());
    return n;
  }
  int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& f) const {
    const Response resp = trace_response(*log, x);
    const auto rows = static_cast<Eigen::Index>(values()), cols = static_cast<Eigen::Index>(windows.size()) + 1;
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(rows, cols);
    Eigen::VectorXd y(rows);
    Eigen::Index row = 0;
    for (std::size_t k = 0; k < windows.size(); ++k)
      for (const std::size_t i : windows[k]) {
        const double r = resp.at((1 + 1e-3 * x[1]) * (*tv)[i] + x[0]);
        a(row, static_cast<Eigen::Index>(k)) = 1;
        a(row, cols - 1) = std::isfinite(r) ? r : 0;
        y[row++] = (*s)[i];
      }
    f = y - a * a.colPivHouseholderQr().solve(y);
    return 0;
  }
};

/// Refines `a` by the whole-trace fit; keeps `a` when the fit fails or moves further than the events allow.
void refine_on_trace(const ForceLog& log, const std::vector<ForcePress>& presses, const std::vector<double>& tv,
                     const std::vector<double>& signal, const AlignmentOptions& o, ClockAlignment& a) {
  TraceResiduals f{&log, &tv, &signal, {}};
  for (std::size_t k = 0; k < presses.size(); ++k) {
    // From this press's rest to the next press's rest (or 4 τ_off after its release).
    const double from = presses[k].rest_start_s;
    const double to = k + 1 < presses.size() ? presses[k + 1].rest_start_s : presses[k].end_s + 4 * o.tau_off_s;
    std::vector<std::size_t> w;
    for (std::size_t i = 0; i < tv.size(); ++i) {
      const double g = a.to_gauge(tv[i]);
      if (g >= from && g < to) w.push_back(i);
    }
    if (w.size() >= 8) f.windows.push_back(std::move(w));
  }
  if (f.windows.size() < 3) return;
  Eigen::VectorXd x(6);
  x << a.offset_s, 1e3 * a.drift, std::log(o.tau_on_s), std::log(o.tau_off_s), 0.35, std::log(0.2);
  Eigen::NumericalDiff<TraceResiduals> nd(f, 1e-4);
  Eigen::LevenbergMarquardt<Eigen::NumericalDiff<TraceResiduals>> lm(nd);
  lm.parameters.maxfev = 400;
  lm.minimize(x);
  if (!x.allFinite()) return;
  Eigen::MatrixXd jac(f.values(), 6);
  nd.df(x, jac);
  Eigen::VectorXd res(f.values());
  f(x, res);
  // Residuals of neighbouring frames are correlated (the pulse, slow drift): the covariance is scaled by the
  // residuals' correlation length (1 + 2·Σρ over lags while positive).
  double c0 = res.squaredNorm(), inflation = 1;
  for (Eigen::Index lag = 1; lag < 50 && lag < res.size(); ++lag) {
    const double rho = res.head(res.size() - lag).dot(res.tail(res.size() - lag)) / c0;
    if (rho <= 0) break;
    inflation += 2 * rho;
  }
  const double dof = std::max(1.0, double(res.size()) - 7 - double(f.windows.size()));
  const Eigen::MatrixXd cov = inflation * c0 / dof * (jac.transpose() * jac).inverse();
  // The model is not the skin (ramps, overshoot, a nonlinearity of another shape): the presses' jackknife (each
  // window left out once, refitted) gives the spread that misfit causes; the σ is the larger of the two.
  const std::size_t n = f.windows.size();
  Eigen::ArrayXd jk_offset(static_cast<Eigen::Index>(n)), jk_drift(static_cast<Eigen::Index>(n));
  for (std::size_t k = 0; k < n; ++k) {
    TraceResiduals fk{&log, &tv, &signal, f.windows};
    fk.windows.erase(fk.windows.begin() + static_cast<std::ptrdiff_t>(k));
    Eigen::VectorXd xk = x;
    Eigen::NumericalDiff<TraceResiduals> ndk(fk, 1e-4);
    Eigen::LevenbergMarquardt<Eigen::NumericalDiff<TraceResiduals>> lmk(ndk);
    lmk.parameters.maxfev = 200;
    lmk.minimize(xk);
    jk_offset[static_cast<Eigen::Index>(k)] = xk[0], jk_drift[static_cast<Eigen::Index>(k)] = 1e-3 * xk[1];
  }
  auto jackknife = [n](const Eigen::ArrayXd& v) { return std::sqrt(double(n - 1) / double(n) * (v - v.mean()).square().sum()); };
  const double offset_sigma = std::max(std::sqrt(cov(0, 0)), jackknife(jk_offset));
  const double drift_sigma = std::max(1e-3 * std::sqrt(cov(1, 1)), jackknife(jk_drift));
  // The events' estimate bounds the refinement: a move beyond 4 of its σ (or a worse σ) is not trusted.
  if (!(std::isfinite(offset_sigma) && offset_sigma < a.offset_sigma_s && std::abs(x[0] - a.offset_s) < 4 * a.offset_sigma_s + 0.05))
    return;
  a.offset_s = x[0], a.drift = 1e-3 * x[1];
  a.offset_sigma_s = offset_sigma, a.drift_sigma = drift_sigma;
  a.tau_on_s = std::exp(x[2]), a.tau_off_s = std::exp(x[3]);
  a.trace_fit = true;
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
  refine_on_trace(log, presses, tv, signal, o, a);
  if (std::abs(a.drift) > o.max_drift)
    throw InputError(file, "clock", "drifts by " + std::to_string(a.drift * 1e6) + " ppm against the video, beyond the " +
                                        std::to_string(o.max_drift * 1e6) + " ppm allowed",
                     "check the log's time unit and that it belongs to this recording");
  a.correlation = correlation(resp, tv, signal, a.offset_s, a.drift);
  a.lag_s = (a.trace_fit ? a.tau_on_s : o.tau_on_s) * std::log(2.0);  // the response model's half-rise delay behind a force step
  return a;
}

}  // namespace clearfit
