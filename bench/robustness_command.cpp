// clearfit-bench robustness: each real-capture effect of clearfit simulate
// (motion, glare, exposure / white balance, flicker, and all of them through
// simulation.preset realistic) at a few strengths, assessed with the
// corrections on and with the effect's correction switched off, on the
// wristband sample and on a doubly curved shell (a spherical cap, not a
// cylinder). Scored against the simulation's truth: the largest centroid error
// of the hotspots found, the per-vertex Pearson correlation of the assessed
// pressure with the truth (contact vertices seen), misses and false hotspots.
// It runs the clearfit program (simulate, calibrate-pressure, assess) beside
// this one; the table goes to stdout, robustness.csv and robustness.json.
#include <clearfit/atomic_file.hpp>
#include "map_scenes.hpp"

#include <clearfit/cli/commands.hpp>
#include <clearfit/error.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/fit/simulate.hpp>
#include <nlohmann/json.hpp>

#include <Eigen/Core>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>

namespace clearfit::cli {

namespace fs = std::filesystem;

namespace {

struct Effect {
  std::string name, strength, yaml;  ///< yaml: simulation keys (two-space indent)
  std::vector<std::string> switches;  ///< the assessment's options that turn its correction off
};

/// The effects and strengths (0 is the clean row). Strengths chosen before any figure was seen.
std::vector<Effect> effects(bool quick) {
  const std::vector<std::string> motion_off{"--no-motion-compensation"}, glare_off{"--no-glare-mask"},
      gains_off{"--no-exposure-normalisation"};
  std::vector<Effect> all = {
      {"none", "0", "", {}},
      {"motion", "mild", "  motion: {drift_px_per_s: 0.5, tremor_px: 0.3, rotation_deg: 0.3}\n", motion_off},
      {"motion", "strong", "  motion: {step_px: 0.05, drift_px_per_s: 2, tremor_px: 1, rotation_deg: 1}\n", motion_off},
      {"glare", "mild", "  glare:\n    - {center: [0.36, 0.6], sigma: 0.02, peak: 0.1, phases: both}\n"
                        "    - {center: [0.66, 0.42], sigma: 0.015, peak: 0.05, phases: worn}\n", glare_off},
      {"glare", "strong", "  glare:\n    - {center: [0.36, 0.6], sigma: 0.03, peak: 0.4, phases: both}\n"
                          "    - {center: [0.66, 0.42], sigma: 0.025, peak: 0.2, phases: worn}\n", glare_off},
      {"exposure", "mild", "  exposure:\n    steps: [{t_s: 0.8, gain: [1.03, 1.03, 1.03]}, {t_s: 1.8, gain: [0.98, 1.0, 1.03]}]\n"
                           "    drift_per_s: [0.005, 0.0, -0.005]\n", gains_off},
      {"exposure", "strong", "  exposure:\n    steps: [{t_s: 0.8, gain: [1.08, 1.08, 1.08]}, {t_s: 1.8, gain: [0.93, 1.0, 1.08]}]\n"
                             "    drift_per_s: [0.02, 0.0, -0.02]\n", gains_off},
      {"flicker", "mild", "  flicker: {amplitude: 0.03, hz: 100, drift_hz_per_s: 0.2}\n", gains_off},
      {"flicker", "strong", "  flicker: {amplitude: 0.1, hz: 100, drift_hz_per_s: 1.0}\n", gains_off},
      {"realistic", "preset", "  preset: realistic\n", {"--no-motion-compensation", "--no-glare-mask", "--no-exposure-normalisation"}},
  };
  if (!quick) return all;
  std::vector<Effect> q;
  for (const Effect& e : all)
    if (e.strength == "mild" || e.name == "none") q.push_back(e);
  return q;
}

struct Part {
  std::string name;
  fs::path mesh, camera;
};

struct Settings {
  fs::path clearfit, out;
  double scale = 0.25, baseline_s = 1.5, press_s = 2.0, fps = 30;
  int window_frames = 30;
  bool quick = false;
};

std::string quoted(const std::string& s) { return "'" + s + "'"; }

/// Runs clearfit with `args` in `dir`; the exit code, stderr's text in `err`.
int run_clearfit(const Settings& st, const fs::path& dir, const std::vector<std::string>& args, std::string* err = nullptr) {
  std::string cmd = "cd " + quoted(dir.string()) + " && " + quoted(st.clearfit.string());
  for (const auto& a : args) cmd += " " + quoted(a);
  cmd += " > clearfit.out 2> clearfit.err";
  const int rc = std::system(cmd.c_str());
  if (err) {
    std::ifstream in(dir / "clearfit.err");
    std::stringstream s;
    s << in.rdbuf();
    *err = s.str();
  }
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

std::string part_yaml(const Part& p, const fs::path& camera) {
  return "mesh: " + p.mesh.string() + "\ncontact: {group: contact}\ncamera: " + camera.string() + "\nmap: {mode: adaptive}\n";
}

/// Renders the part with `effect_yaml` into dir/caps (with presses when asked).
void render(const Settings& st, const Part& p, const fs::path& dir, const std::string& effect_yaml, bool presses) {
  fs::create_directories(dir);
  std::ostringstream y;
  y << part_yaml(p, p.camera) << "simulation:\n  seed: 21\n  format: huffyuv\n  scale: " << st.scale << "\n  timeline: {fps: " << st.fps
    << ", baseline_s: " << st.baseline_s << ", press_s: " << st.press_s << "}\n  skin: {tone: medium}\n"
    << "  pressure:\n    texel_mm: 0.1\n    sources:\n"
    << "      - {name: a, type: gaussian, center_part_mm: [-6, 3, 30], peak_kpa: 14, sigma_mm: 1.6}\n"
    << "      - {name: b, type: gaussian, center_part_mm: [6, -3, 30], peak_kpa: 10, sigma_mm: 1.2}\n"
    << "  presses: {diameters_mm: [3], levels: 9, repetitions: 3}\n"
    << effect_yaml;
  write_file_atomically(dir / "simulate.yaml", y.str());
  std::vector<std::string> args{"simulate", "simulate.yaml", "--out", "caps", "--quiet"};
  if (!presses) args.push_back("--no-presses");
  std::string err;
  if (run_clearfit(st, dir, args, &err) != 0) throw InputError((dir / "simulate.yaml").string(), "", "clearfit simulate failed: " + err);
}

struct Row {
  std::string part, effect, strength, corrections;
  bool refused = false;
  std::string message;
  double centroid_mm = NAN, pearson = NAN, assess_s = NAN;
  int misses = 0, false_hotspots = 0;
};

/// Assesses caps with the clean calibration (and `switches`), scores it against caps' truth.
Row assess(const Settings& st, const Part& p, const fs::path& dir, const fs::path& caps, const fs::path& calibration,
           const std::vector<std::string>& switches, const std::string& out_name) {
  Row row;
  std::ostringstream y;
  y << part_yaml(p, caps / "camera.cameramodel") << "outputs: {folder: " << out_name << ", texel_mm: 0.1}\ncaptures: {baseline: "
    << (caps / "baseline.mkv").string() << ", worn: " << (caps / "worn.mkv").string() << ", window_frames: " << st.window_frames
    << "}\ncalibration: {pressure: " << calibration.string() << ", person: wearer-1}\nassess: {smoothing_mm: 0.5}\n";
  write_file_atomically(dir / (out_name + ".yaml"), y.str());
  std::vector<std::string> args{"assess", out_name + ".yaml", "--quiet", "--no-html"};
  args.insert(args.end(), switches.begin(), switches.end());
  std::string err;
  const auto t0 = std::chrono::steady_clock::now();
  const int rc = run_clearfit(st, dir, args, &err);
  row.assess_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (rc != 0) {
    row.refused = true;
    row.message = err.substr(0, err.find('\n'));
    // The table's cell: what was refused, without the program's name and the capture's folder.
    if (const auto at = row.message.find(".mkv: "); at != std::string::npos) row.message = row.message.substr(at + 6);
    return row;
  }
  std::ifstream rin(dir / out_name / "report.json"), tin(caps / "truth.json");
  const nlohmann::json report = nlohmann::json::parse(rin), truth = nlohmann::json::parse(tin);
  std::vector<Eigen::Vector3d> measured, expected;
  for (const auto& h : report["hotspots"])
    if (h["threshold_kpa"].get<double>() == 4.3 && h["centre_of_pressure_mm"].is_array())
      measured.emplace_back(h["centre_of_pressure_mm"][0], h["centre_of_pressure_mm"][1], h["centre_of_pressure_mm"][2]);
  for (const auto& h : truth["hotspots"])
    if (!h["centroid_part_mm"].is_null()) expected.emplace_back(h["centroid_part_mm"][0], h["centroid_part_mm"][1], h["centroid_part_mm"][2]);
  auto nearest = [](const Eigen::Vector3d& x, const std::vector<Eigen::Vector3d>& set) {
    double best = INFINITY;
    for (const auto& y : set) best = std::min(best, (x - y).norm());
    return best;
  };
  double worst = 0;
  bool any = false;
  for (const auto& t : expected) {
    const double d = nearest(t, measured);
    if (d <= 1.0) worst = std::max(worst, d), any = true;
    else ++row.misses;
  }
  for (const auto& m : measured) row.false_hotspots += nearest(m, expected) > 1.0;
  row.centroid_mm = any ? worst : NAN;
  row.pearson = sim::vertex_pressure_pearson(dir / out_name / "vertices.csv", caps / "truth_vertex_pressure.npy");
  return row;
}

std::string cell(double v, int digits) { return std::isfinite(v) ? fixed(v, digits) : std::string("-"); }
nlohmann::json number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

std::vector<Row> bench_part(const Settings& st, const Part& p) {
  const fs::path root = st.out / p.name;
  std::cerr << "clearfit-bench robustness: " << p.name << ": clean captures and the calibration\n";
  render(st, p, root / "none-0", "", true);
  const fs::path calibration = root / "none-0" / "caps" / "calibration.json";
  std::string err;
  if (run_clearfit(st, root / "none-0",
                   {"calibrate-pressure", "--presses", "caps/presses.csv", "--person", "wearer-1", "--camera", "caps/camera.cameramodel", "--out",
                    "caps/calibration.json"},
                   &err) != 0)
    throw InputError(p.name, "", "clearfit calibrate-pressure failed: " + err);
  std::vector<Row> rows;
  for (const Effect& e : effects(st.quick)) {
    const fs::path dir = root / (e.name + "-" + e.strength);
    if (e.name != "none") render(st, p, dir, e.yaml, false);
    std::vector<std::pair<std::string, std::vector<std::string>>> runs{{"on", {}}};
    if (!e.switches.empty() && !st.quick) runs.push_back({"off", e.switches});
    for (const auto& [label, switches] : runs) {
      Row r = assess(st, p, dir, dir / "caps", calibration, switches, "assess-" + label);
      r.part = p.name, r.effect = e.name, r.strength = e.strength, r.corrections = e.switches.empty() ? "-" : label;
      std::cerr << "  " << r.effect << " " << r.strength << " " << r.corrections << ": "
                << (r.refused ? "refused: " + r.message : "centroid " + cell(r.centroid_mm, 3) + " mm, Pearson " + cell(r.pearson, 3)) << "\n";
      rows.push_back(r);
    }
  }
  return rows;
}

void write_results(const Settings& st, const std::vector<Row>& rows) {
  std::ostringstream csv, table;
  csv << "part,effect,strength,corrections,refused,centroid_error_mm,pearson_vertex,misses,false_hotspots,assess_s\n";
  table << "| part | effect | strength | corrections | centroid error (mm) | Pearson (vertex) | misses | false hotspots | assess (s) |\n"
        << "|---|---|---|---|---|---|---|---|---|\n";
  nlohmann::json j = {{"schema", "clearfit.bench-robustness/1"},
                      {"scale", st.scale},
                      {"timeline", {{"fps", st.fps}, {"baseline_s", st.baseline_s}, {"press_s", st.press_s}}},
                      {"rows", nlohmann::json::array()}};
  for (const Row& r : rows) {
    csv << r.part << ',' << r.effect << ',' << r.strength << ',' << r.corrections << ',' << (r.refused ? 1 : 0) << ','
        << (std::isfinite(r.centroid_mm) ? fixed(r.centroid_mm, 4) : "") << ',' << (std::isfinite(r.pearson) ? fixed(r.pearson, 4) : "")
        << ',' << r.misses << ',' << r.false_hotspots << ',' << fixed(r.assess_s, 2) << '\n';
    if (r.refused)
      table << "| " << r.part << " | " << r.effect << " | " << r.strength << " | " << r.corrections << " | refused: " << r.message.substr(0, r.message.find(" ("))
            << " | | | | " << fixed(r.assess_s, 1) << " |\n";
    else
      table << "| " << r.part << " | " << r.effect << " | " << r.strength << " | " << r.corrections << " | " << cell(r.centroid_mm, 3) << " | "
            << cell(r.pearson, 3) << " | " << r.misses << " | " << r.false_hotspots << " | " << fixed(r.assess_s, 1) << " |\n";
    j["rows"].push_back({{"part", r.part}, {"effect", r.effect}, {"strength", r.strength}, {"corrections", r.corrections},
                         {"refused", r.refused}, {"message", r.message}, {"centroid_error_mm", number(r.centroid_mm)},
                         {"pearson_vertex", number(r.pearson)}, {"misses", r.misses}, {"false_hotspots", r.false_hotspots},
                         {"assess_s", r.assess_s}});
  }
  write_file_atomically(st.out / "robustness.csv", csv.str());
  write_file_atomically(st.out / "robustness.json", j.dump(2) + "\n");
  write_file_atomically(st.out / "robustness.md", table.str());
  std::cout << table.str();
}

}  // namespace

Run add_bench_robustness(CLI::App& app) {
  auto st = std::make_shared<Settings>();
  auto clearfit_exe = std::make_shared<std::string>();
  auto samples = std::make_shared<std::string>(CLEARFIT_SAMPLES_DIR);
  CLI::App* sub = app.add_subcommand("robustness", "Each real-capture effect at a few strengths, corrections on and off, against the "
                                                   "simulated truth (wristband and a doubly curved shell)");
  sub->add_option("--out", st->out, "Folder for the captures, assessments and robustness.{csv,json,md}")->required();
  sub->add_flag("--quick", st->quick, "Smoke test: the wristband, none and the mild strength of each effect, corrections on, at scale 0.2 and a 1 s + 1 s timeline");
  sub->add_option("--scale", st->scale, "Render at this fraction of the camera's resolution")->capture_default_str()->check(CLI::Range(0.05, 1.0));
  sub->add_option("--clearfit", *clearfit_exe, "The clearfit program (default: ../cli/clearfit beside this program)");
  sub->add_option("--samples", *samples, "The samples folder (wristband/)")->capture_default_str();
  return [st, clearfit_exe, samples]() {
    st->clearfit = clearfit_exe->empty() ? fs::canonical("/proc/self/exe").parent_path().parent_path() / "cli" / "clearfit" : fs::path(*clearfit_exe);
    if (!fs::exists(st->clearfit)) throw InputError(st->clearfit.string(), "", "the clearfit program is not there", "give --clearfit");
    if (st->quick) st->scale = std::min(st->scale, 0.2), st->baseline_s = 1.0, st->press_s = 1.0, st->fps = 20, st->window_frames = 20;
    fs::create_directories(st->out);
    st->out = fs::canonical(st->out);
    const fs::path wrist = fs::path(*samples) / "wristband";
    // The shell: a spherical cap (inner radius 30 mm, as the wristband's, 2.5 mm thick, 30° half-angle) under the wristband's camera.
    const fs::path shell = st->out / "shell.obj";
    save_mesh(bench::cap_shell(), shell);
    std::vector<Row> rows;
    std::vector<Part> parts{{"wristband", wrist / "wristband.obj", wrist / "camera.cameramodel"}};
    if (!st->quick) parts.push_back({"shell", shell, wrist / "camera.cameramodel"});
    for (const Part& p : parts)
      for (Row& r : bench_part(*st, p)) rows.push_back(std::move(r));
    write_results(*st, rows);
    return 0;
  };
}

static const Registration registered{"robustness", 30, add_bench_robustness};

}  // namespace clearfit::cli
