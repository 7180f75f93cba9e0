// clearfit assess: the fit assessment of a scene — captures → blanching →
// pressure → hotspots → heatmap on the mesh and the report.
#include "commands.hpp"
#include "part_setup.hpp"
#include "provenance.hpp"

#include <chrono>
#include <clearfit/error.hpp>
#include <clearfit/fit/assessment.hpp>
#include <clearfit/reports/assessment_report.hpp>
#include <clearfit/reports/report_html.hpp>
#include <clearfit/refraction/inverse_map.hpp>
#include <cmath>
#include <clearfit/atomic_file.hpp>
#include <clearfit/npy.hpp>
#include <fstream>
#include <iostream>
#include <unistd.h>

namespace clearfit::cli {
namespace {

namespace fs = std::filesystem;

struct AssessOpts {
  std::string scene_file;
  Scene scene;
  SceneFields::Options options;
  CacheOptions cache;
  bool no_html = false, quiet = false;
};

std::string fmt(double v, int digits = 1) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

/// Outputs go to a staging folder beside the target, which replaces the target
/// only when everything is written: a failed run leaves the old folder as it was.
class StagedFolder {
 public:
  explicit StagedFolder(fs::path target) : target_(std::move(target)) {
    const fs::path parent = target_.parent_path().empty() ? fs::path(".") : target_.parent_path();
    std::error_code ec;
    fs::create_directories(parent, ec);
    if (!fs::is_directory(parent))
      throw InputError(target_.string(), "", "the folder " + parent.string() + " cannot be created", "check the path and its permissions");
    staging_ = parent / ("." + target_.filename().string() + ".partial-" + std::to_string(::getpid()));
    fs::remove_all(staging_);
    fs::create_directories(staging_);
  }
  ~StagedFolder() {
    std::error_code ignored;
    if (!committed_) fs::remove_all(staging_, ignored);
  }
  const fs::path& path() const { return staging_; }
  void commit() {
    const fs::path old = target_.parent_path() / ("." + target_.filename().string() + ".old-" + std::to_string(::getpid()));
    std::error_code ec;
    if (fs::exists(target_)) fs::rename(target_, old);
    fs::rename(staging_, target_);
    fs::remove_all(old, ec);
    committed_ = true;
  }

 private:
  fs::path target_, staging_;
  bool committed_ = false;
};

void add_assess_options(CLI::App& sub, AssessOpts& o) {
  o.options = add_scene_options(sub, o.scene, {"", "contact", "map", "outputs.folder", "outputs.texel_mm", "captures", "calibration", "assess"});
  add_cache_options(sub, o.cache);
  sub.add_flag("--no-html", o.no_html, "Do not write report.html");
  sub.add_flag("--quiet", o.quiet, "No progress on stderr");
}

/// Everything an assessment needs before reading the captures.
struct Prepared {
  std::unique_ptr<LoadedPart> part;
  RefractionMap map;
  InverseMap inverse;
  std::optional<PressureCalibration> calibration;
  std::vector<std::string> notes;
  std::string cache;
  AssessmentOptions options;
  CaptureSources sources;
  AssessmentScene view() const {
    return {&part->mesh, &part->contact, &*part->chart, &part->camera, part->cam_from_part, &map, &inverse};
  }
};

/// Reads the scene (the command line wins), checks the options, loads and
/// traces the part, reads the calibration.
std::unique_ptr<Prepared> prepare(AssessOpts& o) {
  auto p = std::make_unique<Prepared>();
  read_scene(o.scene_file, o.scene, o.options);
  Scene& sc = o.scene;
  if (sc.outputs.folder.empty()) sc.outputs.folder = (sc.file.parent_path() / "out").string();
  const CapturesSection& cap = sc.captures;
  if (cap.both.empty() && (cap.baseline.empty() || cap.worn.empty()))
    throw InputError(o.scene_file, "captures", "a phase is missing: give 'baseline' (not worn) and 'worn', or 'both'",
                     "see the scene file format in README.md");
  if (!o.quiet) std::cerr << "clearfit assess: loading the part and tracing the refraction map\n";
  p->part = load_part_scene(sc, true, std::cerr);
  p->map = compute_part_map(*p->part, o.cache, &p->cache);
  InverseMapOptions iopt;
  iopt.texel_mm = sc.outputs.texel_mm;
  iopt.uv_min = p->part->chart->uv_min;
  iopt.uv_max = p->part->chart->uv_max;
  iopt.compute_errors = false;
  p->inverse = compute_inverse_map(p->map, iopt, &p->part->contact);
  if (!o.quiet)
    std::cerr << "  map: " << p->map.stats.by_status[0] << " pixels see the skin (" << fmt(100 * p->map.stats.coverage)
              << " %), cache " << p->cache << "; chart " << p->inverse.width << " x " << p->inverse.height << " texels of "
              << fmt(sc.outputs.texel_mm, 3) << " mm\n";
  if (!sc.calibration.pressure.empty()) {
    p->calibration = read_pressure_calibration(sc.calibration.pressure);
    p->notes = check_calibration_matches(*p->calibration, sc.calibration.person, format_intrinsics_hash(p->part->camera.intrinsics_hash()));
  }
  AssessmentOptions& ao = p->options;
  ao.window_frames = cap.window_frames;
  ao.compensate_motion = cap.motion_compensation;
  ao.max_motion_px = cap.max_motion_px;
  const AssessSection& as = sc.assess;
  ao.blanching.smoothing_mm = as.smoothing_mm;
  if (!as.reference_uv_mm.empty()) ao.blanching.reference_uv_mm = Vec2(as.reference_uv_mm[0], as.reference_uv_mm[1]);
  ao.blanching.reference_radius_mm = as.reference_radius_mm;
  ao.thresholds_kpa = as.thresholds_kpa;
  ao.min_hotspot_area_mm2 = as.min_hotspot_area_mm2;
  ao.glare = as.glare.options;
  ao.normalise_gains = as.normalise_exposure;
  p->sources = {cap.baseline, cap.worn, cap.both};
  return p;
}

/// Progress lines on stderr: "  stage 10% 20% ...".
std::function<void(const std::string&, int, int)> progress_printer(bool quiet) {
  auto last_stage = std::make_shared<std::string>();
  auto last_percent = std::make_shared<int>(-1);
  return [=](const std::string& stage, int done, int total) {
    if (quiet) return;
    if (stage != *last_stage) {
      if (!last_stage->empty()) std::cerr << "\n";
      *last_stage = stage;
      *last_percent = -1;
      std::cerr << "  " << stage << std::flush;
    }
    if (total > 0) {
      const int percent = 100 * done / total;
      if (percent / 10 != *last_percent / 10) std::cerr << " " << percent << "%" << std::flush;
      *last_percent = percent;
    }
  };
}

}  // namespace

Run add_assess(CLI::App& app) {
  auto o = std::make_shared<AssessOpts>();
  CLI::App* sub = app.add_subcommand("assess", "The fit assessment: where and how hard the part presses, from a not-worn and a worn capture");
  sub->add_option("scene", o->scene_file, "Scene file (YAML): part, camera, captures, calibration, outputs")->required();
  add_assess_options(*sub, *o);

  return [o]() {
    const auto t0 = std::chrono::steady_clock::now();
    const auto p = prepare(*o);
    const Scene& sc = o->scene;
    StagedFolder staged(sc.outputs.folder);
    p->options.progress = progress_printer(o->quiet);
    const AssessmentScene scene = p->view();
    const LoadedPart* part = p->part.get();
    const RefractionMap& map = p->map;
    const auto& calibration = p->calibration;
    const Assessment a = assess_captures(scene, p->sources, calibration, p->options);
    if (!o->quiet) std::cerr << "\n";
    const auto& notes = p->notes;

    AssessmentContext ctx;
    ctx.clearfit_version = CLEARFIT_VERSION;
    ctx.scene = fs::absolute(sc.file).lexically_normal().string();
    ctx.mesh_name = fs::path(sc.part.mesh).filename().string();
    ctx.ior = sc.part.indices.n_part;
    ctx.medium_ior = sc.part.indices.n_medium;
    ctx.fast_path = map.stats.fast_path;
    ctx.chart_method = std::string(to_string(part->chart->method));
    ctx.pose_source = part->pose_source;
    ctx.camera_source = sc.part.camera;
    ctx.calibration = calibration ? &*calibration : nullptr;
    const CapturesSection& cap = sc.captures;
    for (auto [role, path] : {std::pair{"scene", o->scene_file}, {"mesh", sc.part.mesh}, {"camera", sc.part.camera}, {"pose", sc.part.pose},
                              {"baseline", cap.baseline}, {"worn", cap.worn}, {"capture", cap.both}, {"calibration", sc.calibration.pressure}})
      if (!path.empty()) ctx.inputs.push_back({role, path, sha256_of_path(path)});
    const MapOptions& mo = part->map_options;
    ctx.options = {{"ior", mo.indices.n_part},
                   {"medium_ior", mo.indices.n_medium},
                   {"skin_ior", mo.indices.n_skin},
                   {"normals", mo.normals == MapOptions::Normals::flat ? "flat" : "smooth"},
                   {"map_mode", mo.mode == MapOptions::Mode::grid ? "grid" : mo.mode == MapOptions::Mode::adaptive ? "adaptive" : "exact"},
                   {"tolerance_um", mo.tolerance_um},
                   {"texel_mm", sc.outputs.texel_mm},
                   {"window_frames", cap.window_frames},
                   {"motion_compensation", cap.motion_compensation},
                   {"max_motion_px", cap.max_motion_px},
                   {"smoothing_mm", sc.assess.smoothing_mm},
                   {"thresholds_kpa", sc.assess.thresholds_kpa},
                   {"min_hotspot_area_mm2", sc.assess.min_hotspot_area_mm2},
                   {"glare_mask", sc.assess.glare.options.enabled},
                   {"glare_margin_px", sc.assess.glare.options.margin_px},
                   {"exposure_normalisation", sc.assess.normalise_exposure},
                   {"person", sc.calibration.person}};
    for (const auto& n : notes) std::cerr << "clearfit: note: " << n << "\n";
    ctx.run_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    write_assessment_outputs(a, scene, part->normals, ctx, staged.path());
    std::string html_note;
    if (!o->no_html) {
      try {
        const auto result = reports::write_report_html(staged.path());
        for (const auto& n : result.notes) std::cerr << "clearfit: note: " << n << "\n";
      } catch (const InputError& e) {
        html_note = std::string("report.html not written: ") + e.what();
      }
    }
    staged.commit();

    std::cout << "assessed " << ctx.mesh_name << ": " << fmt(a.coverage.seen_area_mm2, 0) << " of " << fmt(a.coverage.contact_area_mm2, 0)
              << " mm² of the contact surface seen; signal noise " << fmt(a.signal.noise_sigma, 4) << "\n";
    if (a.calibrated)
      std::cout << "pressure: peak " << fmt(a.peak_kpa) << " kPa, mean " << fmt(a.mean_kpa) << " kPa over the seen skin\n";
    std::cout << a.hotspots.size() << (a.hotspots.size() == 1 ? " hotspot" : " hotspots") << "\n";
    for (const Hotspot& h : a.hotspots) {
      std::cout << "  #" << h.id << ": peak " << fmt(h.peak, a.calibrated ? 1 : 4) << (a.calibrated ? " ± " + fmt(h.peak_sigma) + " kPa" : "")
                << ", area";
      for (const HotspotLevel& l : h.levels)
        std::cout << (&l == &h.levels.front() ? " " : ", ") << fmt(l.area_mm2, 2) << " mm² >= "
                  << (a.calibrated ? fmt(l.threshold) + " kPa" : fmt(l.threshold, 4));
      std::cout << ", centroid (" << fmt(h.centroid_mm.x(), 2) << ", " << fmt(h.centroid_mm.y(), 2) << ", " << fmt(h.centroid_mm.z(), 2)
                << ") mm";
      if (h.unseen_area_mm2 > 0) std::cout << ", " << fmt(h.unseen_area_mm2, 2) << " mm² unseen beside it";
      std::cout << "\n";
    }
    for (const auto& w : a.warnings) std::cout << "warning: " << w << "\n";
    if (!html_note.empty()) std::cout << "warning: " << html_note << "\n";
    const fs::path report = fs::path(sc.outputs.folder) / (o->no_html || !html_note.empty() ? "report.json" : "report.html");
    std::cout << "report: " << fs::absolute(report).lexically_normal().string() << "\n";
    return 0;
  };
}

static const Registration registered{"assess", 30, add_assess};

namespace {

/// Seconds to decode every frame of a capture, nothing else (the same reader).
double bare_decode_s(const fs::path& source, int* frames) {
  const auto t = std::chrono::steady_clock::now();
  FrameReader reader(source);
  cv::Mat frame;
  int n = 0;
  while (reader.read(frame)) ++n;
  *frames = n;
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

/// 3D distance from the median texel of `a` to the nearest texel of `b` (mm).
double median_nearest_mm(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  if (a.empty() || b.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::vector<double> d;
  for (const Vec3& p : a) {
    double best = INFINITY;
    for (const Vec3& q : b) best = std::min(best, (p - q).squaredNorm());
    d.push_back(std::sqrt(best));
  }
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

/// The crest of a field near `centre`: contact texels within 3 mm whose value
/// is at least 95 % of the largest there (a punch's rim ring, a Gaussian's top).
std::vector<Vec3> crest(const Assessment& a, const std::vector<float>& value, const Vec3& centre) {
  double top = -INFINITY;
  std::vector<std::size_t> near;
  for (std::size_t k = 0; k < value.size(); ++k)
    if (a.raster.face[k] >= 0 && std::isfinite(value[k]) && (a.raster.point[k] - centre).norm() < 3.0)
      near.push_back(k), top = std::max(top, static_cast<double>(value[k]));
  std::vector<Vec3> out;
  for (std::size_t k : near)
    if (value[k] >= 0.95 * top) out.push_back(a.raster.point[k]);
  return out;
}

/// Accuracy of an assessment against a simulation's truth (truth.json and
/// truth_pressure.npy written by clearfit simulate). Texels the camera does not
/// see are neither misses nor zeros: they are left out of the RMSE, the
/// sensitivity and the false alarms, and the share of the truth's pressed area
/// they hold is reported beside.
nlohmann::json accuracy_against_truth(const Assessment& a, const fs::path& truth_dir, double range_kpa) {
  std::ifstream in(truth_dir / "truth.json");
  if (!in) throw InputError((truth_dir / "truth.json").string(), "", "not found", "give --truth the folder clearfit simulate wrote");
  const nlohmann::json t = nlohmann::json::parse(in);
  const npy::Float32Array tp = npy::read_float32(truth_dir / "truth_pressure.npy");
  const auto& grid = t.at("chart_grid");
  ChartField truth;
  truth.grid.width = grid.at("width");
  truth.grid.height = grid.at("height");
  truth.grid.texel_mm = grid.at("texel_mm");
  truth.grid.uv_origin = Vec2(grid.at("uv_origin_mm")[0], grid.at("uv_origin_mm")[1]);
  truth.value = tp.values;
  if (tp.values.size() != truth.grid.size())
    throw InputError((truth_dir / "truth_pressure.npy").string(), "shape", "does not match truth.json's chart_grid");
  const ChartGrid& g = a.signal.y.grid;
  std::vector<float> truth_here(g.size(), std::numeric_limits<float>::quiet_NaN());
  double se = 0, pressed_mm2 = 0, pressed_unseen_mm2 = 0;
  long long n = 0, pos = 0, tp_n = 0, neg = 0, fp = 0;
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const auto k = g.index(i, j);
      if (a.raster.face[k] < 0) continue;
      const float tv = truth.sample(g.uv(i, j));
      truth_here[k] = tv;
      if (!std::isfinite(tv)) continue;
      const bool seen = std::isfinite(a.signal.y.value[k]);
      if (tv >= 5.5f) pressed_mm2 += a.raster.area_mm2[k], pressed_unseen_mm2 += seen ? 0.0 : a.raster.area_mm2[k];
      float est = a.calibrated ? a.pressure.value[k] : 0.f;
      if (a.calibrated && a.pressure_status[k] == static_cast<std::uint8_t>(PressureStatus::below_detection)) est = 0.f;
      if (!seen || !std::isfinite(est)) continue;
      se += (est - tv) * (est - tv);
      ++n;
      const bool detected = a.calibrated ? est >= 5.5f : false;
      if (tv >= 5.5f) ++pos, tp_n += detected;
      if (tv < 4.3f) ++neg, fp += detected;
    }
  nlohmann::json hotspots = nlohmann::json::array();
  for (const auto& th : t.at("hotspots")) {
    if (th.at("centroid_part_mm").is_null()) continue;
    const Vec3 c(th["centroid_part_mm"][0], th["centroid_part_mm"][1], th["centroid_part_mm"][2]);
    const Hotspot* best = nullptr;
    for (const Hotspot& h : a.hotspots)
      if (h.centre_of_pressure_mm.allFinite() && (!best || (h.centre_of_pressure_mm - c).norm() < (best->centre_of_pressure_mm - c).norm()))
        best = &h;
    nlohmann::json area55 = nullptr;
    if (best && a.calibrated)
      for (const HotspotLevel& l : best->levels)
        if (l.threshold == 5.5) area55 = l.area_mm2;
    const double crest_mm = a.calibrated ? median_nearest_mm(crest(a, a.pressure.value, c), crest(a, truth_here, c)) : NAN;
    hotspots.push_back({{"truth_centroid_mm", {c.x(), c.y(), c.z()}},
                        {"truth_peak_kpa", th.value("peak_kpa", 0.0)},
                        {"truth_area_5_5_mm2", th.value("area_ge_5_5_kpa_mm2", 0.0)},
                        {"found", best != nullptr},
                        {"centroid_error_mm", best ? nlohmann::json((best->centre_of_pressure_mm - c).norm()) : nlohmann::json(nullptr)},
                        {"peak_kpa", best && a.calibrated ? nlohmann::json(best->peak) : nlohmann::json(nullptr)},
                        {"area_5_5_mm2", area55},
                        {"unseen_beside_mm2", best ? nlohmann::json(best->unseen_area_mm2) : nlohmann::json(nullptr)},
                        {"crest_error_mm", std::isfinite(crest_mm) ? nlohmann::json(crest_mm) : nlohmann::json(nullptr)}});
  }
  const double rmse = n ? std::sqrt(se / n) : 0;
  return {{"texels_compared", n},
          {"rmse_kpa", a.calibrated ? nlohmann::json(rmse) : nlohmann::json(nullptr)},
          {"rmse_percent_of_range", a.calibrated ? nlohmann::json(100 * rmse / range_kpa) : nlohmann::json(nullptr)},
          {"sensitivity_5_5", pos && a.calibrated ? nlohmann::json(static_cast<double>(tp_n) / pos) : nlohmann::json(nullptr)},
          {"false_alarm_rate_5_5", neg && a.calibrated ? nlohmann::json(static_cast<double>(fp) / neg) : nlohmann::json(nullptr)},
          {"truth_pressed_area_mm2", pressed_mm2},
          {"pressed_unseen_fraction", pressed_mm2 > 0 ? pressed_unseen_mm2 / pressed_mm2 : 0.0},
          {"hotspots", hotspots}};
}

}  // namespace

Run add_bench_assess(CLI::App& app) {
  auto o = std::make_shared<AssessOpts>();
  auto truth = std::make_shared<std::string>();
  auto json_out = std::make_shared<std::string>();
  CLI::App* bench = app.get_subcommand("bench");
  CLI::App* sub = bench->add_subcommand("assess", "The assessment's throughput against a bare decode of the same captures, "
                                                  "and its accuracy against a simulation's truth");
  sub->add_option("scene", o->scene_file, "Scene file (YAML) with captures")->required();
  sub->add_option("--truth", *truth, "Folder with truth.json and truth_pressure.npy (clearfit simulate); default: the captures' folder if it has them");
  sub->add_option("--json", *json_out, "Also write the figures as JSON");
  add_assess_options(*sub, *o);
  return [o, truth, json_out]() {
    o->quiet = true;
    const auto p = prepare(*o);
    // Bare decode of the same captures, then the assessment (map from the cache).
    int frames = 0;
    double decode_s = 0;
    for (const auto& src : {p->sources.baseline, p->sources.worn, p->sources.both})
      if (!src.empty()) {
        int n = 0;
        decode_s += bare_decode_s(src, &n);
        frames += n;
      }
    const auto t = std::chrono::steady_clock::now();
    const Assessment a = assess_captures(p->view(), p->sources, p->calibration, p->options);
    const double assess_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
    const CameraModel& cam = p->part->camera;
    nlohmann::json r = {{"schema", "clearfit.bench-assess/1"},
                        {"image", {cam.width, cam.height}},
                        {"frames", frames},
                        {"bare_decode_fps", frames / decode_s},
                        {"assessment_fps", frames / assess_s},
                        {"ratio_to_decode", decode_s / assess_s},
                        {"per_frame_work_fps", a.work_ms > 0 ? frames / (a.work_ms / 1000) : 0.0},
                        {"per_frame_work_ms", frames ? a.work_ms / frames : 0.0},
                        {"assessment_s", assess_s}};
    fs::path truth_dir = *truth;
    if (truth_dir.empty()) {
      const fs::path first = !p->sources.both.empty() ? p->sources.both : p->sources.baseline;
      if (fs::exists(first.parent_path() / "truth.json")) truth_dir = first.parent_path();
    }
    const double range = p->calibration ? std::max(p->calibration->p_max_kpa, 1.0) : 30.0;
    if (!truth_dir.empty()) r["accuracy"] = accuracy_against_truth(a, truth_dir, range);
    std::cout << "clearfit bench assess: " << fs::path(o->scene_file).filename().string() << " (" << cam.width << "x" << cam.height << ", "
              << frames << " frames)\n";
    std::cout << "  bare decode        " << fmt(frames / decode_s, 1) << " frames/s\n";
    std::cout << "  whole assessment   " << fmt(frames / assess_s, 1) << " frames/s = " << fmt(100 * decode_s / assess_s, 0)
              << " % of the bare decode rate (target >= 80 %)\n";
    std::cout << "  per-frame work     " << fmt(r["per_frame_work_ms"].get<double>(), 2) << " ms/frame = "
              << fmt(r["per_frame_work_fps"].get<double>(), 0) << " frames/s with decode excluded (target >= 240)\n";
    if (r.contains("accuracy")) {
      const auto& acc = r["accuracy"];
      if (!acc["rmse_kpa"].is_null())
        std::cout << "  pressure RMSE      " << fmt(acc["rmse_kpa"].get<double>(), 2) << " kPa = " << fmt(acc["rmse_percent_of_range"].get<double>(), 1)
                  << " % of the calibrated range " << fmt(range, 1) << " kPa (target <= 10 %)\n";
      if (!acc["sensitivity_5_5"].is_null())
        std::cout << "  >= 5.5 kPa         sensitivity " << fmt(100 * acc["sensitivity_5_5"].get<double>(), 1) << " % (target >= 90 %), false alarms "
                  << fmt(100 * acc["false_alarm_rate_5_5"].get<double>(), 2) << " % of texels below 4.3 kPa\n";
      std::cout << "  unseen             " << fmt(100 * acc["pressed_unseen_fraction"].get<double>(), 1) << " % of the truth's "
                << fmt(acc["truth_pressed_area_mm2"].get<double>(), 2) << " mm² >= 5.5 kPa is not seen (not scored)\n";
      for (const auto& h : acc["hotspots"])
        std::cout << "  hotspot at (" << fmt(h["truth_centroid_mm"][0].get<double>(), 2) << ", " << fmt(h["truth_centroid_mm"][1].get<double>(), 2)
                  << ", " << fmt(h["truth_centroid_mm"][2].get<double>(), 2) << ") mm: "
                  << (h["found"].get<bool>() ? "centroid error " + fmt(h["centroid_error_mm"].get<double>(), 3) + " mm (target <= 0.3)" : std::string("not found"))
                  << (h["peak_kpa"].is_null() ? "" : ", peak " + fmt(h["peak_kpa"].get<double>()) + " kPa (truth " + fmt(h["truth_peak_kpa"].get<double>()) + ")")
                  << (h["area_5_5_mm2"].is_null() ? "" : ", area >= 5.5 kPa " + fmt(h["area_5_5_mm2"].get<double>(), 2) + " mm² (truth " + fmt(h["truth_area_5_5_mm2"].get<double>(), 2) + ")")
                  << (h["crest_error_mm"].is_null() ? "" : ", crest " + fmt(h["crest_error_mm"].get<double>(), 3) + " mm from the truth's")
                  << (h["unseen_beside_mm2"].is_null() || h["unseen_beside_mm2"].get<double>() == 0 ? ""
                                                        : ", " + fmt(h["unseen_beside_mm2"].get<double>(), 2) + " mm² unseen beside it")
                  << "\n";
    }
    if (!json_out->empty()) write_file_atomically(*json_out, r.dump(2) + "\n");
    return 0;
  };
}

static const Registration registered_bench{"bench assess", 91, add_bench_assess};

}  // namespace clearfit::cli
