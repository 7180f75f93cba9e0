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
#include <iostream>
#include <unistd.h>

namespace clearfit::cli {
namespace {

namespace fs = std::filesystem;

struct AssessOpts {
  std::string scene, out, baseline, worn, both, calibration, person;
  int window_frames = 100;
  double max_motion_px = 10.0, smoothing_mm = 0.25, texel_mm = 0.05, min_area_mm2 = 0.05;
  std::vector<double> thresholds_kpa{4.3, 5.5};
  std::vector<double> reference_uv;
  double reference_radius_mm = 2.0;
  bool no_motion = false, no_html = false, quiet = false;
  PartOptions part;
};

template <class T>
void take(const CLI::App& sub, const char* option, T& field, const std::optional<T>& value) {
  if (value && sub.count(option) == 0) field = *value;
}

/// The scene's captures / calibration / assess sections.
void read_assess_sections(const SceneFile& sc, const CLI::App& sub, AssessOpts& o) {
  SceneReader r(sc.path);
  const YAML::Node& root = sc.root;
  if (const YAML::Node c = root["captures"]) {
    r.only_keys(c, "captures", {"baseline", "worn", "both", "window_frames", "max_motion_px", "motion_compensation"});
    take(sub, "--baseline", o.baseline, r.path(c, "baseline", "captures.baseline"));
    take(sub, "--worn", o.worn, r.path(c, "worn", "captures.worn"));
    take(sub, "--both", o.both, r.path(c, "both", "captures.both"));
    take(sub, "--window-frames", o.window_frames, r.get<int>(c, "window_frames", "captures.window_frames", "a whole number of frames"));
    take(sub, "--max-motion-px", o.max_motion_px, r.get<double>(c, "max_motion_px", "captures.max_motion_px", "a number of pixels"));
    if (const auto m = r.get<bool>(c, "motion_compensation", "captures.motion_compensation", "true or false"); m && sub.count("--no-motion-compensation") == 0)
      o.no_motion = !*m;
  }
  if (const YAML::Node c = root["calibration"]) {
    r.only_keys(c, "calibration", {"pressure", "person"});
    take(sub, "--calibration", o.calibration, r.path(c, "pressure", "calibration.pressure"));
    take(sub, "--person", o.person, r.get<std::string>(c, "person", "calibration.person", "a person's id"));
  }
  if (const YAML::Node a = root["assess"]) {
    r.only_keys(a, "assess", {"smoothing_mm", "thresholds_kpa", "reference_uv_mm", "reference_radius_mm", "min_hotspot_area_mm2"});
    take(sub, "--smoothing-mm", o.smoothing_mm, r.get<double>(a, "smoothing_mm", "assess.smoothing_mm", "a length in mm"));
    take(sub, "--min-hotspot-area-mm2", o.min_area_mm2, r.get<double>(a, "min_hotspot_area_mm2", "assess.min_hotspot_area_mm2", "an area in mm²"));
    take(sub, "--reference-radius-mm", o.reference_radius_mm, r.get<double>(a, "reference_radius_mm", "assess.reference_radius_mm", "a length in mm"));
    auto numbers = [&](const char* key, const char* full, std::vector<double>& out, const char* option, std::size_t count) {
      const YAML::Node n = a[key];
      if (!n || sub.count(option) > 0) return;
      if (!n.IsSequence() || (count && n.size() != count) || n.size() == 0)
        r.fail(n, full, count ? "expected " + std::to_string(count) + " numbers" : "expected a list of numbers");
      out.clear();
      for (const auto& e : n) {
        try {
          out.push_back(e.as<double>());
        } catch (const YAML::Exception&) {
          r.fail(e, full, "expected a number, got '" + e.Scalar() + "'");
        }
      }
    };
    numbers("thresholds_kpa", "assess.thresholds_kpa", o.thresholds_kpa, "--thresholds-kpa", 0);
    numbers("reference_uv_mm", "assess.reference_uv_mm", o.reference_uv, "--reference-uv-mm", 2);
  }
  take(sub, "--out", o.out, sc.out_folder);
  take(sub, "--texel-mm", o.texel_mm, sc.texel_mm);
}

void check_positive(const char* option, double v) {
  if (!(std::isfinite(v) && v > 0)) throw InputError("", option, "must be a positive number");
}

/// Outputs go to a staging folder beside the target, which replaces the target
/// only when everything is written: a failed run leaves the old folder as it was.
class StagedFolder {
 public:
  explicit StagedFolder(fs::path target) : target_(std::move(target)) {
    const fs::path parent = target_.parent_path().empty() ? fs::path(".") : target_.parent_path();
    if (!fs::is_directory(parent))
      throw InputError(target_.string(), "", "the folder " + parent.string() + " does not exist", "create it first");
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

std::string fmt(double v, int digits = 1) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

}  // namespace

Run add_assess(CLI::App& app) {
  auto o = std::make_shared<AssessOpts>();
  CLI::App* sub = app.add_subcommand("assess", "The fit assessment: where and how hard the part presses, from a not-worn and a worn capture");
  sub->add_option("scene", o->scene, "Scene file (YAML): part, camera, captures, calibration, outputs")->required();
  sub->add_option("--out", o->out, "Output folder (default: the scene's outputs.folder, else out/ beside the scene)");
  sub->add_option("--baseline", o->baseline, "Not-worn capture: a video or a folder of images");
  sub->add_option("--worn", o->worn, "Worn capture: a video or a folder of images");
  sub->add_option("--both", o->both, "One capture holding the baseline and then the press (split automatically)");
  sub->add_option("--calibration", o->calibration, "Per-person pressure calibration (from clearfit calibrate-pressure)");
  sub->add_option("--person", o->person, "Who wears the part (checked against the calibration)");
  sub->add_option("--window-frames", o->window_frames, "Frames averaged per phase")->capture_default_str();
  sub->add_option("--max-motion-px", o->max_motion_px, "Motion beyond this is refused, px")->capture_default_str();
  sub->add_flag("--no-motion-compensation", o->no_motion, "Do not measure or undo motion between frames");
  sub->add_option("--smoothing-mm", o->smoothing_mm, "Gaussian smoothing of the signal on the chart, mm")->capture_default_str();
  sub->add_option("--thresholds-kpa", o->thresholds_kpa, "Hotspot thresholds, kPa")->delimiter(',')->capture_default_str();
  sub->add_option("--reference-uv-mm", o->reference_uv, "Centre u,v (chart mm) of an unpressed reference disk (default: automatic)")
      ->delimiter(',')->expected(2);
  sub->add_option("--reference-radius-mm", o->reference_radius_mm, "Radius of the reference disk, mm")->capture_default_str();
  sub->add_option("--min-hotspot-area-mm2", o->min_area_mm2, "Smaller hotspots are dropped, mm²")->capture_default_str();
  sub->add_option("--texel-mm", o->texel_mm, "Texel size of the chart grid, mm")->capture_default_str();
  sub->add_flag("--no-html", o->no_html, "Do not write report.html");
  sub->add_flag("--quiet", o->quiet, "No progress on stderr");
  add_part_options(*sub, o->part);

  return [o, sub]() {
    const auto t0 = std::chrono::steady_clock::now();
    const SceneFile sc = read_scene(o->scene);
    take_scene_part_options(sc, *sub, o->part);
    read_assess_sections(sc, *sub, *o);
    if (o->out.empty()) o->out = (sc.path.parent_path() / "out").string();
    if (o->window_frames < 1) throw InputError(o->scene, "captures.window_frames", "must be at least 1 frame");
    check_positive("--max-motion-px", o->max_motion_px);
    check_positive("--texel-mm", o->texel_mm);
    check_positive("--min-hotspot-area-mm2", o->min_area_mm2);
    check_positive("--reference-radius-mm", o->reference_radius_mm);
    if (!(std::isfinite(o->smoothing_mm) && o->smoothing_mm >= 0)) throw InputError("", "--smoothing-mm", "must be >= 0");
    for (double t : o->thresholds_kpa) check_positive("--thresholds-kpa", t);
    if (!o->both.empty() && (!o->baseline.empty() || !o->worn.empty()))
      throw InputError(o->scene, "captures", "give either 'both' or 'baseline' and 'worn', not all three");
    if (o->both.empty() && (o->baseline.empty() || o->worn.empty()))
      throw InputError(o->scene, "captures", "a phase is missing: give 'baseline' (not worn) and 'worn', or 'both'",
                       "see the scene file format in README.md");
    StagedFolder staged(o->out);
    auto say = [&](const std::string& line) {
      if (!o->quiet) std::cerr << line << std::flush;
    };

    say("clearfit assess: loading the part and tracing the refraction map\n");
    const auto part = load_part_scene(o->part, true, std::cerr);
    std::string cache;
    const RefractionMap map = compute_part_map(*part, o->part, &cache);
    InverseMapOptions iopt;
    iopt.texel_mm = o->texel_mm;
    iopt.uv_min = part->chart->uv_min;
    iopt.uv_max = part->chart->uv_max;
    iopt.compute_errors = false;
    const InverseMap inverse = compute_inverse_map(map, iopt, &part->contact);
    say("  map: " + std::to_string(map.stats.by_status[0]) + " pixels see the skin (" + fmt(100 * map.stats.coverage) +
        " %), cache " + cache + "; chart " + std::to_string(inverse.width) + " x " + std::to_string(inverse.height) + " texels of " +
        fmt(o->texel_mm, 3) + " mm\n");

    std::optional<PressureCalibration> calibration;
    std::vector<std::string> notes;
    if (!o->calibration.empty()) {
      calibration = read_pressure_calibration(o->calibration);
      notes = check_calibration_matches(*calibration, o->person,
                                        format_intrinsics_hash(part->camera.intrinsics_hash()));
    }

    AssessmentOptions ao;
    ao.window_frames = o->window_frames;
    ao.compensate_motion = !o->no_motion;
    ao.max_motion_px = o->max_motion_px;
    ao.blanching.smoothing_mm = o->smoothing_mm;
    if (!o->reference_uv.empty()) ao.blanching.reference_uv_mm = Vec2(o->reference_uv[0], o->reference_uv[1]);
    ao.blanching.reference_radius_mm = o->reference_radius_mm;
    ao.thresholds_kpa = o->thresholds_kpa;
    ao.min_hotspot_area_mm2 = o->min_area_mm2;
    int last_percent = -1;
    std::string last_stage;
    ao.progress = [&](const std::string& stage, int done, int total) {
      if (o->quiet) return;
      if (stage != last_stage) {
        if (!last_stage.empty()) std::cerr << "\n";
        last_stage = stage;
        last_percent = -1;
        std::cerr << "  " << stage << std::flush;
      }
      if (total > 0) {
        const int percent = 100 * done / total;
        if (percent / 10 != last_percent / 10) std::cerr << " " << percent << "%" << std::flush;
        last_percent = percent;
      } else if (done > 0 && done % 50 == 0) {
        std::cerr << " " << done << std::flush;
      }
    };
    CaptureSources sources{o->baseline, o->worn, o->both};
    AssessmentScene scene{&part->mesh, &part->contact, &*part->chart, &part->camera, part->cam_from_part, &map, &inverse};
    const Assessment a = assess_captures(scene, sources, calibration, ao);
    if (!o->quiet) std::cerr << "\n";

    AssessmentContext ctx;
    ctx.clearfit_version = CLEARFIT_VERSION;
    ctx.scene = fs::absolute(sc.path).lexically_normal().string();
    ctx.mesh_name = fs::path(o->part.mesh).filename().string();
    ctx.ior = o->part.ior;
    ctx.medium_ior = o->part.medium_ior;
    ctx.fast_path = map.stats.fast_path;
    ctx.chart_method = std::string(to_string(part->chart->method));
    ctx.pose_source = part->pose_source;
    ctx.camera_source = o->part.camera;
    ctx.calibration = calibration ? &*calibration : nullptr;
    for (auto [role, path] : {std::pair{"scene", o->scene}, {"mesh", o->part.mesh}, {"camera", o->part.camera}, {"pose", o->part.pose},
                              {"baseline", o->baseline}, {"worn", o->worn}, {"capture", o->both}, {"calibration", o->calibration}})
      if (!path.empty()) ctx.inputs.push_back({role, path, sha256_of_path(path)});
    ctx.options = {{"ior", o->part.ior},
                   {"medium_ior", o->part.medium_ior},
                   {"skin_ior", o->part.skin_ior},
                   {"normals", o->part.normals},
                   {"map_mode", o->part.mode},
                   {"tolerance_um", o->part.tolerance_um},
                   {"texel_mm", o->texel_mm},
                   {"window_frames", o->window_frames},
                   {"motion_compensation", !o->no_motion},
                   {"max_motion_px", o->max_motion_px},
                   {"smoothing_mm", o->smoothing_mm},
                   {"thresholds_kpa", o->thresholds_kpa},
                   {"min_hotspot_area_mm2", o->min_area_mm2},
                   {"person", o->person}};
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
      std::cout << "  #" << h.id << (a.calibrated ? " >= " + fmt(h.threshold) + " kPa" : " signal >= " + fmt(h.threshold, 4)) << ": peak "
                << fmt(h.peak, a.calibrated ? 1 : 4) << (a.calibrated ? " ± " + fmt(h.peak_sigma) + " kPa" : "") << ", area "
                << fmt(h.area_mm2, 2) << " mm², centroid (" << fmt(h.centroid_mm.x(), 2) << ", " << fmt(h.centroid_mm.y(), 2) << ", "
                << fmt(h.centroid_mm.z(), 2) << ") mm\n";
    }
    for (const auto& w : a.warnings) std::cout << "warning: " << w << "\n";
    if (!html_note.empty()) std::cout << "warning: " << html_note << "\n";
    const fs::path report = fs::path(o->out) / (o->no_html || !html_note.empty() ? "report.json" : "report.html");
    std::cout << "report: " << fs::absolute(report).lexically_normal().string() << "\n";
    return 0;
  };
}

static const Registration registered{"assess", 30, add_assess};

}  // namespace clearfit::cli
