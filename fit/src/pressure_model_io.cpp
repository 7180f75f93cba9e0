// Files of the pressure calibration: the presses' CSV (input) and the
// calibration JSON (`clearfit.pressure-calibration/1`).
#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>
#include <clearfit/utf8.hpp>
#include <clearfit/fit/pressure_model.hpp>
#include <clearfit/fit/skin_blur.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <numbers>
#include <optional>
#include <sstream>

namespace clearfit {

namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr const char* kSchema = "clearfit.pressure-calibration/1";

std::string trim(std::string_view s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string_view::npos) return {};
  return std::string(s.substr(b, s.find_last_not_of(" \t") - b + 1));
}

std::vector<std::string> split_commas(const std::string& line) {
  std::vector<std::string> fields;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = line.find(',', start);
    fields.push_back(trim(std::string_view(line).substr(start, comma == std::string::npos ? std::string::npos : comma - start)));
    if (comma == std::string::npos) return fields;
    start = comma + 1;
  }
}

/// The ';'-separated ring profile columns of one row (both or neither; edges increasing, one signal per ring).
void read_profile(const std::vector<std::string>& fields, const std::map<std::string, int>& col, const std::string& file,
                  const std::string& where, CalibrationPress& c) {
  const auto e = col.find("ring_edges_mm"), y = col.find("ring_signal");
  if (e == col.end() && y == col.end()) return;
  if (e == col.end() || y == col.end())
    throw InputError(file, where, "gives one of ring_edges_mm and ring_signal without the other", "give both or neither");
  auto list = [&](const std::string& field, const char* name) {
    std::vector<double> out;
    std::size_t start = 0;
    while (start <= field.size()) {
      const std::size_t end = std::min(field.find(';', start), field.size());
      double v = 0;
      const auto [ptr, ec] = std::from_chars(field.data() + start, field.data() + end, v);
      if (ec != std::errc() || ptr != field.data() + end || !std::isfinite(v))
        throw InputError(file, where + ", column '" + name + "'", "expected ';'-separated numbers, found '" + field + "'");
      out.push_back(v);
      start = end + 1;
    }
    return out;
  };
  if (fields[e->second].empty() && fields[y->second].empty()) return;
  c.ring_edges_mm = list(fields[e->second], "ring_edges_mm");
  c.ring_signal = list(fields[y->second], "ring_signal");
  bool increasing = c.ring_edges_mm.size() >= 2 && c.ring_edges_mm[0] >= 0;
  for (std::size_t k = 1; k < c.ring_edges_mm.size(); ++k) increasing = increasing && c.ring_edges_mm[k] > c.ring_edges_mm[k - 1];
  if (!increasing || c.ring_signal.size() + 1 != c.ring_edges_mm.size())
    throw InputError(file, where, "ring_edges_mm must be n + 1 increasing radii >= 0 and ring_signal n values (found " +
                     std::to_string(c.ring_edges_mm.size()) + " and " + std::to_string(c.ring_signal.size()) + ")");
}

}  // namespace

std::vector<CalibrationPress> read_presses_csv(const std::filesystem::path& path, std::vector<std::string>* notes) {
  const std::string file = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(file, "", "cannot open the presses file", "check the path");
  const char* kHint = "columns: trial,indenter_diameter_mm,force_n,mean_pressure_kpa,signal";
  std::string line;
  int line_no = 0;
  std::vector<std::string> header;
  std::map<std::string, int> col;
  std::vector<CalibrationPress> presses;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (const auto bad = first_invalid_utf8(line); bad != std::string::npos)
      throw InputError(file, "line " + std::to_string(line_no) + ", column " + std::to_string(bad + 1),
                       "is not UTF-8 text", "save the file as UTF-8 (trial labels and column names go into JSON outputs)");
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    const std::vector<std::string> fields = split_commas(line);
    const std::string where = "line " + std::to_string(line_no);
    if (header.empty()) {
      header = fields;
      for (std::size_t k = 0; k < header.size(); ++k) {
        if (header[k].empty()) throw InputError(file, where + " (header)", "column " + std::to_string(k + 1) + " has no name", kHint);
        if (!col.emplace(header[k], static_cast<int>(k)).second)
          throw InputError(file, where + " (header)", "column '" + header[k] + "' appears twice", kHint);
        static const std::array<const char*, 11> known{"trial", "indenter_diameter_mm", "force_n", "mean_pressure_kpa", "signal",
                                                       "force_sd_n", "hold_frames", "rest_frames", "ring_edges_mm", "ring_signal",
                                                       "sphere_radius_mm"};
        if (std::find(known.begin(), known.end(), header[k]) == known.end() && notes)
          notes->push_back(file + ": column '" + header[k] + "' is not used");
      }
      for (const char* required : {"trial", "signal"})
        if (!col.count(required))
          throw InputError(file, where + " (header)", std::string("missing column '") + required + "'", kHint);
      if (!col.count("mean_pressure_kpa") && !(col.count("force_n") && col.count("indenter_diameter_mm")))
        throw InputError(file, where + " (header)",
                         "missing column 'mean_pressure_kpa' (or both 'force_n' and 'indenter_diameter_mm')", kHint);
      continue;
    }
    if (fields.size() != header.size())
      throw InputError(file, where, "has " + std::to_string(fields.size()) + " fields, the header has " +
                       std::to_string(header.size()), "one value per column, separated by commas");
    // A numeric field: nullopt when absent or empty; throws on anything but a finite number.
    auto number = [&](const char* name) -> std::optional<double> {
      const auto it = col.find(name);
      if (it == col.end() || fields[it->second].empty()) return std::nullopt;
      const std::string& f = fields[it->second];
      double v = 0;
      const auto [end, ec] = std::from_chars(f.data(), f.data() + f.size(), v);
      const std::string at = where + ", column '" + name + "'";
      if (ec != std::errc() || end != f.data() + f.size())
        throw InputError(file, at, "expected a number, found '" + f + "'", kHint);
      if (!std::isfinite(v)) throw InputError(file, at, "expected a finite number, found '" + f + "'");
      return v;
    };
    CalibrationPress c;
    c.line = line_no;
    c.trial = fields[col.at("trial")];
    if (c.trial.empty()) throw InputError(file, where + ", column 'trial'", "is empty; expected a trial label");
    const auto signal = number("signal");
    if (!signal) throw InputError(file, where + ", column 'signal'", "is empty; expected the signal y (a number)");
    c.signal = *signal;
    const auto force = number("force_n"), diameter = number("indenter_diameter_mm"), pressure = number("mean_pressure_kpa");
    if (force && *force < 0)
      throw InputError(file, where + ", column 'force_n'",
                       "is negative (" + significant_digits(*force, 6) + " N); expected a force >= 0 N",
                       "load-cell readings in newtons, tare removed");
    if (diameter && !(*diameter > 0))
      throw InputError(file, where + ", column 'indenter_diameter_mm'",
                       "must be > 0 mm, found " + significant_digits(*diameter, 6));
    if (pressure && *pressure < 0)
      throw InputError(file, where + ", column 'mean_pressure_kpa'",
                       "is negative (" + significant_digits(*pressure, 6) + " kPa); expected >= 0");
    c.force_n = force.value_or(kNaN);
    c.indenter_diameter_mm = diameter.value_or(kNaN);
    if (const auto sphere = number("sphere_radius_mm")) {
      if (!(*sphere > 0))
        throw InputError(file, where + ", column 'sphere_radius_mm'", "must be > 0 mm, found " + significant_digits(*sphere, 6),
                         "leave it empty for a flat indenter");
      c.sphere_radius_mm = *sphere;
    }
    std::optional<double> computed;
    if (force && diameter) {
      const double r = *diameter / 2;
      computed = 1000.0 * *force / (std::numbers::pi * r * r);  // N/mm² = MPa → kPa
    }
    if (pressure && computed && std::abs(*pressure - *computed) > 0.01 * *computed + 0.01)
      throw InputError(
          file, where,
          "mean_pressure_kpa " + significant_digits(*pressure, 6) +
              " disagrees with force_n / (pi (d/2)^2) = " + significant_digits(*computed, 6) + " kPa",
          "fix one of force_n, indenter_diameter_mm, mean_pressure_kpa, or leave mean_pressure_kpa empty");
    if (!pressure && !computed)
      throw InputError(file, where, "gives no pressure: mean_pressure_kpa is empty and force_n / indenter_diameter_mm are incomplete", kHint);
    c.mean_pressure_kpa = pressure ? *pressure : *computed;
    read_profile(fields, col, file, where, c);
    presses.push_back(std::move(c));
  }
  if (in.bad()) throw InputError(file, "", "read error");
  if (header.empty()) throw InputError(file, "header", "the file is empty; expected a header row", kHint);
  if (presses.empty()) throw InputError(file, "line " + std::to_string(line_no), "no data rows after the header", kHint);
  return presses;
}

std::string format_intrinsics_hash(std::uint64_t hash) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(hash));
  return buf;
}

void write_pressure_calibration(const PressureCalibration& cal, const std::filesystem::path& path) {
  using json = nlohmann::ordered_json;
  auto finite_or_null = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  json params;
  int k = 3;
  if (cal.model == PressureModelKind::logistic) {
    params = {{"y_max", cal.logistic.y_max}, {"p50_kpa", cal.logistic.p50_kpa}, {"width_kpa", cal.logistic.width_kpa}};
  } else {
    params = {{"intercept", cal.intercept}, {"slope_per_kpa", cal.slope_per_kpa}};
    k = 2;
  }
  json cov = json::array();
  for (int i = 0; i < k; ++i) {
    json row = json::array();
    for (int j = 0; j < k; ++j) row.push_back(cal.covariance(i, j));
    cov.push_back(row);
  }
  const PressureEstimate det = cal.invert(cal.detection_signal() * (1 + 1e-12) + 1e-300);
  const PressureEstimate sat = cal.invert(std::numeric_limits<double>::max());
  const json j = {
      {"schema", kSchema},
      {"model", to_string(cal.model)},
      {"person", cal.person},
      {"camera_intrinsics_hash", cal.camera_hash.empty() ? json(nullptr) : json(cal.camera_hash)},
      {"created", cal.created},
      {"parameters", params},
      {"covariance", cov},
      {"noise_sigma", cal.noise_sigma},
      {"pressure_range_kpa", {cal.p_min_kpa, cal.p_max_kpa}},
      {"presses", cal.presses},
      {"skin_blur_mm", finite_or_null(cal.skin_blur_mm)},
      {"quality", {{"rmse_kpa", finite_or_null(cal.rmse_kpa)}, {"r2", finite_or_null(cal.r2)}, {"r2_linear", finite_or_null(cal.r2_linear)}}},
      // Informational (not read back): the limits the inverse applies.
      {"limits", {{"detection_signal", cal.detection_signal()},
                  {"detection_kpa", finite_or_null(det.status == PressureStatus::ok ? det.pressure_kpa : det.bound_kpa)},
                  {"saturation_signal", cal.saturation_signal()},
                  {"saturation_kpa", finite_or_null(sat.bound_kpa)}}}};
  write_file_atomically(path, j.dump(2) + "\n");
}

PressureCalibration read_pressure_calibration(const std::filesystem::path& path) {
  using nlohmann::json;
  const std::string file = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(file, "", "cannot open the pressure calibration file", "check the path, or run clearfit calibrate-pressure");
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  json j;
  try {
    j = json::parse(text);
  } catch (const json::parse_error& e) {
    const std::size_t upto = std::min<std::size_t>(e.byte, text.size());
    const long line = 1 + std::count(text.begin(), text.begin() + static_cast<long>(upto), '\n');
    throw InputError(file, "line " + std::to_string(line), "is not valid JSON", "a clearfit.pressure-calibration/1 file");
  } catch (const json::exception& e) {  // a number beyond double's range (1e309)
    throw InputError(file, "", std::string("is not valid JSON: ") + e.what(), "numbers must be finite doubles");
  }
  if (!j.is_object()) throw InputError(file, "top level", "expected a JSON object");
  // A required key of the given JSON type, named with its dotted path.
  auto get = [&](const json& obj, const std::string& key, const std::string& prefix, json::value_t type) -> const json& {
    const std::string name = "key '" + prefix + key + "'";
    if (!obj.contains(key)) throw InputError(file, name, "is missing", "a clearfit.pressure-calibration/1 file written by clearfit calibrate-pressure");
    const json& v = obj.at(key);
    const bool ok = type == json::value_t::number_float ? v.is_number() : v.type() == type ||
                    (type == json::value_t::number_integer && v.is_number_integer());
    if (!ok) throw InputError(file, name, std::string("has the wrong type (") + v.type_name() + ")");
    return v;
  };
  auto number = [&](const json& obj, const std::string& key, const std::string& prefix = "") {
    return get(obj, key, prefix, json::value_t::number_float).get<double>();
  };
  auto str = [&](const json& obj, const std::string& key) { return get(obj, key, "", json::value_t::string).get<std::string>(); };
  const std::string schema = str(j, "schema");
  if (schema != kSchema)
    throw InputError(file, "key 'schema'", "is '" + schema + "', expected '" + kSchema + "'", "not a pressure calibration of this clearfit version");
  PressureCalibration cal;
  cal.path = path;
  const std::string model = str(j, "model");
  if (model == "logistic") cal.model = PressureModelKind::logistic;
  else if (model == "linear") cal.model = PressureModelKind::linear;
  else throw InputError(file, "key 'model'", "is '" + model + "', expected 'logistic' or 'linear'");
  cal.person = str(j, "person");
  if (cal.person.empty()) throw InputError(file, "key 'person'", "is empty; expected who was calibrated");
  if (!j.contains("camera_intrinsics_hash")) throw InputError(file, "key 'camera_intrinsics_hash'", "is missing", "null for any camera");
  const json& cam = j.at("camera_intrinsics_hash");
  if (!cam.is_null()) {
    if (!cam.is_string()) throw InputError(file, "key 'camera_intrinsics_hash'", "expected a string of 16 hex digits or null");
    cal.camera_hash = cam.get<std::string>();
  }
  cal.created = str(j, "created");
  const json& params = get(j, "parameters", "", json::value_t::object);
  auto positive = [&](double v, const std::string& key) {
    if (!(v > 0) || !std::isfinite(v))
      throw InputError(file, "key '" + key + "'",
                       "must be a finite number > 0, found " + significant_digits(v, 6));
    return v;
  };
  int k = 3;
  if (cal.model == PressureModelKind::logistic) {
    cal.logistic.y_max = positive(number(params, "y_max", "parameters."), "parameters.y_max");
    cal.logistic.p50_kpa = number(params, "p50_kpa", "parameters.");
    cal.logistic.width_kpa = positive(number(params, "width_kpa", "parameters."), "parameters.width_kpa");
  } else {
    cal.intercept = number(params, "intercept", "parameters.");
    cal.slope_per_kpa = positive(number(params, "slope_per_kpa", "parameters."), "parameters.slope_per_kpa");
    k = 2;
  }
  const json& cov = get(j, "covariance", "", json::value_t::array);
  if (cov.size() != static_cast<std::size_t>(k))
    throw InputError(file, "key 'covariance'", "expected a " + std::to_string(k) + "x" + std::to_string(k) + " matrix for the " + model + " model");
  for (int r = 0; r < k; ++r) {
    if (!cov[r].is_array() || cov[r].size() != static_cast<std::size_t>(k))
      throw InputError(file, "key 'covariance', row " + std::to_string(r + 1), "expected " + std::to_string(k) + " numbers");
    for (int c = 0; c < k; ++c) {
      if (!cov[r][c].is_number() || !std::isfinite(cov[r][c].get<double>()))
        throw InputError(file, "key 'covariance', row " + std::to_string(r + 1), "expected finite numbers");
      cal.covariance(r, c) = cov[r][c].get<double>();
    }
  }
  if (!cal.covariance.isApprox(cal.covariance.transpose(), 1e-9) || (cal.covariance.diagonal().array() < 0).any())
    throw InputError(file, "key 'covariance'", "must be symmetric with a non-negative diagonal");
  cal.noise_sigma = number(j, "noise_sigma");
  if (!(cal.noise_sigma >= 0) || !std::isfinite(cal.noise_sigma))
    throw InputError(file, "key 'noise_sigma'", "must be a finite number >= 0");
  const json& range = get(j, "pressure_range_kpa", "", json::value_t::array);
  if (range.size() != 2 || !range[0].is_number() || !range[1].is_number() ||
      !(range[0].get<double>() >= 0 && range[1].get<double>() > range[0].get<double>()))
    throw InputError(file, "key 'pressure_range_kpa'", "expected [p_min, p_max] with 0 <= p_min < p_max (kPa)");
  cal.p_min_kpa = range[0].get<double>();
  cal.p_max_kpa = range[1].get<double>();
  cal.presses = get(j, "presses", "", json::value_t::number_integer).get<int>();
  // The skin blur the fit assumed: optional (files written before it was recorded have none), null for the uniform fit.
  if (j.contains("skin_blur_mm") && !j.at("skin_blur_mm").is_null()) {
    const json& b = j.at("skin_blur_mm");
    if (!b.is_number() || !SkinBlur{b.get<double>()}.valid())
      throw InputError(file, "key 'skin_blur_mm'", std::string("expected ") + SkinBlur::rule + ", or null (not modelled), found " + b.dump(),
                       "the blur the calibration was fitted with (calibrate-pressure --skin-blur-mm)");
    cal.skin_blur_mm = b.get<double>();
  }
  const json& q = get(j, "quality", "", json::value_t::object);
  auto quality = [&](const char* key) {
    if (!q.contains(key)) throw InputError(file, std::string("key 'quality.") + key + "'", "is missing");
    return q.at(key).is_number() ? q.at(key).get<double>() : kNaN;
  };
  cal.rmse_kpa = quality("rmse_kpa");
  cal.r2 = quality("r2");
  cal.r2_linear = quality("r2_linear");
  return cal;
}

std::vector<std::string> check_calibration_matches(const PressureCalibration& cal, const std::string& person,
                                                   const std::string& camera_hash) {
  const std::string file = cal.path.string();
  if (cal.person != person)
    throw InputError(file, "key 'person'", "the calibration is for person '" + cal.person + "', the scene is for '" + person + "'",
                     "calibrate this person (clearfit calibrate-pressure --person " + person + ") or fix the scene's person");
  std::vector<std::string> notes;
  if (cal.camera_hash.empty()) {
    notes.push_back("the pressure calibration names no camera; the camera was not checked");
  } else if (camera_hash.empty()) {
    notes.push_back("no camera hash given; the calibration's camera " + cal.camera_hash + " was not checked");
  } else if (cal.camera_hash != camera_hash) {
    throw InputError(file, "key 'camera_intrinsics_hash'",
                     "the calibration was made with camera " + cal.camera_hash + ", the scene's camera is " + camera_hash,
                     "the signal depends on the camera: calibrate with the scene's camera (--camera)");
  }
  return notes;
}

}  // namespace clearfit
