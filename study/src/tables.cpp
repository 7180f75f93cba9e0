#include <clearfit/study/tables.hpp>

#include "figures.hpp"
#include "files.hpp"

#include <clearfit/error.hpp>
#include <clearfit/fit/pressure_model.hpp>
#include <clearfit/format.hpp>
#include <clearfit/study/fingertip_fe.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

namespace clearfit::study {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

/// A CSV field: numbers with 6 significant digits, null empty, text quoted when needed.
std::string field(const json& v) {
  if (v.is_null()) return "";
  if (v.is_number()) return significant_digits(v.get<double>(), 6);
  if (v.is_boolean()) return v.get<bool>() ? "true" : "false";
  std::string s = v.is_string() ? v.get<std::string>() : v.dump();
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string q = "\"";
  for (char ch : s) q += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return q + "\"";
}

/// Writes rows of a JSON array as CSV with the given columns.
std::string to_csv(const json& rows, const std::vector<std::string>& columns) {
  std::ostringstream out;
  for (std::size_t k = 0; k < columns.size(); ++k) out << (k ? "," : "") << columns[k];
  out << "\n";
  for (const json& row : rows) {
    for (std::size_t k = 0; k < columns.size(); ++k) out << (k ? "," : "") << field(row.value(columns[k], json(nullptr)));
    out << "\n";
  }
  return out.str();
}

void write_file(const fs::path& path, const std::string& text, StudyTables& tables) {
  write_text_atomically(path, text);
  tables.files.push_back(path);
}

json number_or_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

double mean_of(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? NAN : s / double(v.size());
}

json trial_row(const Manifest& m, const JobRecord& r) {
  const Trial& t = m.trials[r.index];
  json row{{"trial", t.id}, {"participant", t.participant}, {"condition", t.condition},
           {"status", r.ok ? "ok" : "failed"}, {"error", r.error}, {"seconds", r.seconds}, {"max_rss_mb", r.max_rss_mb}};
  if (r.ok)
    for (const char* k : {"force_n", "mean_pressure_kpa", "contact_signal", "contact_pressure_kpa", "peak_kpa", "mean_kpa",
                          "hotspots", "blanched_area_mm2", "noise_sigma", "rim_to_centre"})
      row[k] = r.summary.value(k, json(nullptr));
  return row;
}

/// Linear regression and logistic model of contact signal on mean pressure.
json participant_row(const std::string& id, const std::vector<const JobRecord*>& records) {
  json row{{"participant", id}, {"trials", records.size()}};
  std::vector<double> p, y;
  std::vector<CalibrationPress> presses;
  std::size_t failed = 0;
  for (const JobRecord* r : records) {
    if (!r->ok) {
      ++failed;
      continue;
    }
    const json& s = r->summary;
    if (!s.value("mean_pressure_kpa", json()).is_number() || !s.value("contact_signal", json()).is_number()) continue;
    p.push_back(s["mean_pressure_kpa"].get<double>());
    y.push_back(s["contact_signal"].get<double>());
    presses.push_back(CalibrationPress{r->trial, NAN, NAN, p.back(), y.back()});
  }
  row["failed"] = failed;
  row["regression_trials"] = p.size();
  try {
    const LinearRegression lin = linear_regression(p, y);
    row.update({{"linear_r2", lin.r2}, {"linear_slope_per_kpa", lin.slope}, {"linear_intercept", lin.intercept},
                {"linear_p", lin.p_value}});
  } catch (const std::invalid_argument& e) {
    row["note"] = std::string("no linear regression: ") + e.what();
  }
  try {
    PressureFitOptions o;
    o.person = id;
    o.source = "participant " + id;
    const PressureFitResult fit = fit_pressure_calibration(presses, o);
    row.update({{"logistic_y_max", fit.logistic.y_max}, {"logistic_p50_kpa", fit.logistic.p50_kpa},
                {"logistic_width_kpa", fit.logistic.width_kpa}, {"logistic_r2", fit.r2_logistic}});
  } catch (const std::exception& e) {
    row["note"] = row.value("note", std::string()) + (row.contains("note") ? "; " : "") + "no logistic fit: " + e.what();
  }
  return row;
}

/// The study's PLS for a bump condition: its averaged colour profile on the
/// layered model's stress by depth under a punch of the bump's size.
void add_stress_pls(const Condition& c, const RadialProfile& profile, json& row, json& pls_rows) {
  PunchFeOptions fe;
  fe.punch_radius_mm = c.bump->diameter_mm / 2;
  fe.depth_mm = c.bump->height_mm;
  fe.element_mm = std::min(0.1, fe.punch_radius_mm / 4);
  try {
    const PunchStress stress = solve_punch_stress(fe);
    const StressPls pls = stress_profile_pls(profile, stress, 2);
    row.update({{"pls_r2", pls.r2}, {"vip_above_1", pls.important_depths()}, {"punch_force_n", stress.force_n}});
    for (std::size_t k = 0; k < pls.depth_mm.size(); ++k) {
      double peak = 0;
      for (std::size_t i = 0; i < stress.r_mm.size(); ++i) peak = std::max(peak, stress.vm(k, i));
      pls_rows.push_back({{"condition", c.id}, {"depth_mm", pls.depth_mm[k]}, {"vip", pls.vip[k]}, {"peak_von_mises_kpa", peak}});
    }
  } catch (const std::exception& e) {
    row["note"] = std::string("no stress PLS: ") + e.what();
  }
}

/// Per condition: means of the trial figures, the averaged profile and, for a bump, the stress PLS.
json condition_row(const Condition& c, const std::vector<const JobRecord*>& records, json& profiles, json& pls_rows) {
  json row{{"condition", c.id}, {"trials", records.size()}};
  if (c.bump) row.update({{"diameter_mm", c.bump->diameter_mm}, {"height_mm", c.bump->height_mm}});
  std::map<std::string, std::vector<double>> values;
  std::vector<RadialProfile> trial_profiles;
  std::size_t failed = 0;
  for (const JobRecord* r : records) {
    if (!r->ok) {
      ++failed;
      continue;
    }
    for (const char* k : {"contact_signal", "peak_kpa", "contact_pressure_kpa", "blanched_area_mm2"})
      if (r->summary.value(k, json()).is_number()) values[k].push_back(r->summary[k].get<double>());
    if (!r->summary.contains("profile")) continue;
    RadialProfile p;
    const json& j = r->summary["profile"];
    p.position_mm = j["position_mm"].get<std::vector<double>>();
    p.segments = j["segments"].get<std::vector<int>>();
    for (const json& v : j["signal"]) p.value.push_back(v.is_null() ? NAN : v.get<double>());
    trial_profiles.push_back(std::move(p));
  }
  row["failed"] = failed;
  for (const auto& [k, v] : values) row["mean_" + k] = number_or_null(mean_of(v));
  if (!trial_profiles.empty()) {
    const RadialProfile mean = average_profiles(trial_profiles);
    for (std::size_t k = 0; k < mean.position_mm.size(); ++k)
      profiles.push_back({{"condition", c.id}, {"position_mm", mean.position_mm[k]},
                          {"signal", number_or_null(mean.value[k])}, {"segments", mean.segments[k]}});
    if (c.bump) add_stress_pls(c, mean, row, pls_rows);
  }
  return row;
}

/// profiles.png (the averaged colour profile per condition, the study's figure) and vip.png (VIP by depth).
void write_figures(const json& profiles, const json& pls_rows, const fs::path& out, StudyTables& tables) {
  auto curves = [](const json& rows, const char* x, const char* y) {
    std::vector<Curve> c;
    for (const json& r : rows) {
      const std::string id = r["condition"].get<std::string>();
      if (c.empty() || c.back().label != id) c.push_back({id, {}, {}});
      c.back().x.push_back(r[x].get<double>());
      c.back().y.push_back(r[y].is_number() ? r[y].get<double>() : NAN);
    }
    return c;
  };
  if (!profiles.empty()) {
    write_line_plot(curves(profiles, "position_mm", "signal"), "Colour change through the bump centre (mean of 20-degree segments)",
                    "position (mm)", "signal y", 0, out / "profiles.png");
    tables.files.push_back(out / "profiles.png");
  }
  if (!pls_rows.empty()) {
    write_line_plot(curves(pls_rows, "depth_mm", "vip"), "PLS of the colour profile on stress by depth: VIP (1: dashed)",
                    "depth (mm)", "VIP", 1, out / "vip.png");
    tables.files.push_back(out / "vip.png");
  }
}

}  // namespace

StudyTables reduce_study(const Manifest& m, const RunContext& context) {
  StudyTables tables;
  std::vector<JobRecord> records;
  for (std::size_t i = 0; i < m.trials.size(); ++i) {
    records.push_back(read_job_record(m, i, context));
    if (!m.trials[i].problem.empty()) records.back().error = m.path.filename().string() + ": " + m.trials[i].problem;
    (records.back().ok ? tables.ok : tables.failed)++;
  }
  json trials = json::array(), participants = json::array(), conditions = json::array(), profiles = json::array();
  json pls_rows = json::array();
  json failures = json::array();
  for (const JobRecord& r : records) {
    trials.push_back(trial_row(m, r));
    if (!r.ok) failures.push_back({{"trial", r.trial}, {"error", r.error}});
  }
  std::vector<double> r2;
  int sig5 = 0, sig10 = 0;
  for (const Participant& p : m.participants) {
    std::vector<const JobRecord*> mine;
    for (const JobRecord& r : records)
      if (m.trials[r.index].participant == p.id) mine.push_back(&r);
    json row = participant_row(p.id, mine);
    if (row.contains("linear_r2")) {
      r2.push_back(row["linear_r2"].get<double>());
      sig5 += row["linear_p"].get<double>() < 0.05;
      sig10 += row["linear_p"].get<double>() < 0.10;
    }
    participants.push_back(std::move(row));
  }
  for (const Condition& c : m.conditions) {
    std::vector<const JobRecord*> mine;
    for (const JobRecord& r : records)
      if (m.trials[r.index].condition == c.id) mine.push_back(&r);
    conditions.push_back(condition_row(c, mine, profiles, pls_rows));
  }
  tables.summary = {{"schema", "clearfit.study-summary/1"}, {"study", m.study}, {"manifest", m.path.string()},
                    {"jobs", {{"total", records.size()}, {"ok", tables.ok}, {"failed", tables.failed}}},
                    {"failed", failures},
                    {"regression", {{"participants", r2.size()}, {"mean_r2", number_or_null(mean_of(r2))},
                                    {"significant_5pct", sig5}, {"significant_10pct", sig10}, {"study_mean_r2", 0.439}}},
                    {"trials", trials}, {"participants", participants}, {"conditions", conditions}, {"pls", pls_rows}};
  fs::create_directories(context.out);
  write_file(context.out / "trials.csv",
             to_csv(trials, {"trial", "participant", "condition", "status", "force_n", "mean_pressure_kpa", "contact_signal",
                             "contact_pressure_kpa", "peak_kpa", "mean_kpa", "hotspots", "blanched_area_mm2",
                             "noise_sigma", "rim_to_centre", "seconds", "max_rss_mb", "error"}),
             tables);
  write_file(context.out / "participants.csv",
             to_csv(participants, {"participant", "trials", "failed", "regression_trials", "linear_r2", "linear_slope_per_kpa",
                                   "linear_intercept", "linear_p", "logistic_y_max", "logistic_p50_kpa",
                                   "logistic_width_kpa", "logistic_r2", "note"}),
             tables);
  write_file(context.out / "conditions.csv",
             to_csv(conditions, {"condition", "diameter_mm", "height_mm", "trials", "failed", "mean_contact_signal",
                                 "mean_contact_pressure_kpa", "mean_peak_kpa", "mean_blanched_area_mm2", "pls_r2",
                                 "vip_above_1", "punch_force_n", "note"}),
             tables);
  write_file(context.out / "profiles.csv", to_csv(profiles, {"condition", "position_mm", "signal", "segments"}), tables);
  write_file(context.out / "pls.csv", to_csv(pls_rows, {"condition", "depth_mm", "vip", "peak_von_mises_kpa"}), tables);
  write_figures(profiles, pls_rows, context.out, tables);
  write_file(context.out / "study.json", tables.summary.dump(2) + "\n", tables);
  return tables;
}

}  // namespace clearfit::study
