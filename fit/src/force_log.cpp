#include <clearfit/error.hpp>
#include <clearfit/fit/force_log.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

namespace clearfit {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t\r"), b = s.find_last_not_of(" \t\r");
  return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  for (std::string f; std::getline(ss, f, ',');) out.push_back(trim(f));
  return out;
}

/// Column index and unit factor (to s or N) of the first header cell in `units`; -1 if none.
std::pair<int, double> find_column(const std::vector<std::string>& header, const std::map<std::string, double>& units) {
  for (std::size_t k = 0; k < header.size(); ++k)
    if (const auto it = units.find(lower(header[k])); it != units.end()) return {static_cast<int>(k), it->second};
  return {-1, 0};
}

double number(const std::string& text, const std::string& file, int line, const char* what) {
  double v = 0;
  const auto r = std::from_chars(text.data(), text.data() + text.size(), v);
  if (r.ec != std::errc() || r.ptr != text.data() + text.size() || !std::isfinite(v))
    throw InputError(file, "line " + std::to_string(line), std::string("the ") + what + " '" + text + "' is not a finite number");
  return v;
}

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

void check_log(const ForceLog& log, const std::string& file) {
  if (log.time_s.size() < 10)
    throw InputError(file, "", "holds " + std::to_string(log.time_s.size()) + " samples; at least 10 are needed",
                     "give the whole session's force log");
  const double top = *std::max_element(log.force_n.begin(), log.force_n.end());
  const auto at_top = std::count_if(log.force_n.begin(), log.force_n.end(),
                                    [&](double f) { return std::abs(f - top) <= 1e-9 * std::max(1.0, std::abs(top)); });
  if (top > 0 && at_top > std::max<std::ptrdiff_t>(3, static_cast<std::ptrdiff_t>(0.02 * log.force_n.size())))
    throw InputError(file, "force", "reaches its maximum " + std::to_string(top) + " N on " + std::to_string(at_top) +
                                        " samples: the gauge clipped (its range was exceeded)",
                     "press less hard or use a gauge with a larger range");
}

}  // namespace

ForceLog read_force_log(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path.string(), "", "cannot be read", "give the force gauge's CSV log");
  const std::string file = path.string();
  static const std::map<std::string, double> time_units{{"time_s", 1},     {"time_ms", 1e-3},      {"t_s", 1},
                                                        {"t_ms", 1e-3},    {"timestamp_s", 1},     {"timestamp_ms", 1e-3}};
  static const std::map<std::string, double> force_units{
      {"force_n", 1}, {"force_mn", 1e-3}, {"force_kgf", 9.80665}, {"force_gf", 9.80665e-3}, {"force_lbf", 4.4482216152605}};
  ForceLog log;
  log.source = path;
  std::vector<std::string> header;
  int tcol = -1, fcol = -1, line_no = 0;
  double tscale = 1, fscale = 1;
  for (std::string line; std::getline(in, line);) {
    ++line_no;
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    if (header.empty()) {
      header = split(t);
      std::tie(tcol, tscale) = find_column(header, time_units);
      std::tie(fcol, fscale) = find_column(header, force_units);
      if (tcol < 0 || fcol < 0)
        throw InputError(file, "line " + std::to_string(line_no) + " (header)",
                         std::string("has no ") + (tcol < 0 ? "time" : "force") + " column with a unit (got '" + t + "')",
                         "name the columns with their units: time_s or time_ms, and force_n, force_mn, force_kgf, force_gf or force_lbf");
      continue;
    }
    const auto cells = split(t);
    if (static_cast<int>(cells.size()) <= std::max(tcol, fcol))
      throw InputError(file, "line " + std::to_string(line_no), "has " + std::to_string(cells.size()) + " fields, the header " +
                                                                  std::to_string(header.size()));
    const double time = number(cells[tcol], file, line_no, "time") * tscale;
    const double force = number(cells[fcol], file, line_no, "force") * fscale;
    if (!log.time_s.empty() && !(time > log.time_s.back()))
      throw InputError(file, "line " + std::to_string(line_no),
                       "time " + cells[tcol] + " is not after the previous sample's (line " + std::to_string(log.line.back()) +
                           "): samples duplicated or out of order",
                       "give the log as the gauge wrote it, one sample per time");
    log.time_s.push_back(time);
    log.force_n.push_back(force);
    log.line.push_back(line_no);
  }
  if (header.empty()) throw InputError(file, "", "is empty", "give the force gauge's CSV log with a header");
  check_log(log, file);
  // Tare: the rests' level. The lowest fifth of the samples gives it roughly (biased low by the noise);
  // the median of every sample within 20 mN above that is the level itself.
  std::vector<double> sorted = log.force_n;
  std::sort(sorted.begin(), sorted.end());
  const double rough = median(std::vector<double>(sorted.begin(), sorted.begin() + std::max<std::ptrdiff_t>(1, sorted.size() / 5)));
  std::vector<double> rest;
  for (double f : log.force_n)
    if (f < rough + 0.02) rest.push_back(f);
  log.tare_n = median(rest);
  for (double& f : log.force_n) f -= log.tare_n;
  if (std::abs(log.tare_n) > 1e-6) log.notes.push_back("tare of " + std::to_string(log.tare_n) + " N subtracted (the gauge's reading at rest)");
  return log;
}

void PressSegmentation::validate() const {
  auto need = [](bool ok, const char* field, double v, const char* rule) {
    if (!ok) throw std::invalid_argument(std::string(field) + " = " + std::to_string(v) + ": " + rule);
  };
  need(threshold_n > 0, "threshold_n", threshold_n, "must be positive");
  need(settle_s >= 0, "settle_s", settle_s, "must be ≥ 0");
  need(min_hold_s > 0, "min_hold_s", min_hold_s, "must be positive");
  need(min_rest_s > 0, "min_rest_s", min_rest_s, "must be positive");
  need(settled_band > 0 && settled_band < 1, "settled_band", settled_band, "must be in (0, 1)");
}

std::vector<ForcePress> find_presses(const ForceLog& log, const PressSegmentation& o) {
  o.validate();
  const auto& t = log.time_s;
  const auto& f = log.force_n;
  std::vector<ForcePress> presses;
  double previous_end = t.front();
  for (std::size_t i = 0; i < t.size();) {
    if (f[i] <= o.threshold_n) {
      ++i;
      continue;
    }
    std::size_t e = i;
    while (e + 1 < t.size() && f[e + 1] > o.threshold_n) ++e;
    ForcePress p;
    p.start_s = t[i];
    p.end_s = t[e];
    std::vector<double> hold;
    for (std::size_t k = i; k <= e; ++k)
      if (t[k] >= p.start_s + o.settle_s) hold.push_back(f[k]);
    const double med = median(hold);
    bool found = false;
    for (std::size_t k = i; k <= e; ++k) {
      if (t[k] < p.start_s + o.settle_s || std::abs(f[k] - med) > o.settled_band * med) continue;
      if (!found) p.hold_start_s = t[k];
      p.hold_end_s = t[k];
      found = true;
    }
    if (found && p.hold_end_s - p.hold_start_s >= o.min_hold_s) {
      std::vector<double> settled, sq;
      for (std::size_t k = i; k <= e; ++k)
        if (t[k] >= p.hold_start_s && t[k] <= p.hold_end_s) settled.push_back(f[k]);
      p.force_n = median(settled);
      double ss = 0;
      for (double v : settled) ss += (v - p.force_n) * (v - p.force_n);
      p.force_sd_n = std::sqrt(ss / std::max<std::size_t>(1, settled.size() - 1));
      p.rest_end_s = p.start_s - 0.2;
      p.rest_start_s = std::max(previous_end + 0.5 * (p.start_s - previous_end), p.start_s - 5.0);
      presses.push_back(p);
    }
    if (t[e] - t[i] >= 0.25) previous_end = p.end_s;  // a noise spike above the threshold does not end a rest
    i = e + 1;
  }
  if (presses.empty())
    throw InputError(log.source.string(), "", "shows no press (force above " + std::to_string(o.threshold_n) + " N held for " +
                                                  std::to_string(o.settle_s + o.min_hold_s) + " s)",
                     "check the force column and its unit");
  return presses;
}

}  // namespace clearfit
