// The assessment's preparation, shared by clearfit assess and clearfit-bench assess.
#include <clearfit/cli/assess_setup.hpp>
#include <clearfit/cli/commands.hpp>

#include <clearfit/error.hpp>
#include <iostream>

namespace clearfit::cli {

void add_assess_options(CLI::App& sub, AssessOpts& o) {
  o.options = add_scene_options(sub, o.scene, {"", "contact", "map", "outputs.folder", "outputs.texel_mm", "captures", "baseline", "calibration", "assess"});
  add_cache_options(sub, o.cache);
  sub.add_flag("--no-html", o.no_html, "Do not write report.html");
  sub.add_flag("--quiet", o.quiet, "No progress on stderr");
}

namespace {

/// kPa thresholds without a pressure calibration (the hotspots are then found on the blanching signal).
/// Asked for on the command line, for this run: refused. Set in the scene file: a warning, not an error,
/// since a scene file's settings serve every run of it, with a calibration (calibration.pressure or
/// --calibration) or without one.
void warn_or_refuse_kpa_thresholds(const Scene& sc, const SceneFields::Options& options, std::vector<std::string>& warnings) {
  if (given_on_command_line(options, "assess.thresholds_kpa"))
    throw InputError("", "--thresholds-kpa", "needs a pressure calibration: without one clearfit reports the blanching signal, not kPa",
                     "give --calibration CAL.json (clearfit calibrate-pressure), or --signal-threshold / --significance-sigmas for the signal");
  const auto it = sc.file_keys.find("assess.thresholds_kpa");
  if (it == sc.file_keys.end()) return;
  warnings.push_back(sc.file.string() + ": line " + std::to_string(it->second) + ", key 'assess.thresholds_kpa': ignored, since the " +
                     "scene has no calibration.pressure (hotspots are found on the blanching signal, not in kPa); give " +
                     "calibration.pressure or --calibration CAL.json (clearfit calibrate-pressure) for kPa thresholds, or " +
                     "assess.signal_thresholds / significance_sigmas for thresholds on the signal");
}

/// The skin's blur the assessment undoes (fit/skin_blur.hpp), and where it came from. A calibration's field fit maps
/// the signal to the contact pressure blurred by the blur it assumed (PressureCalibration::skin_blur_mm), so an
/// assessment undoing another blur reads its pressure through a curve that does not hold for it: the calibration's
/// blur is taken when neither the scene file nor the command line gives one, and a blur given is kept (it was asked
/// for) with a warning when it differs from the calibration's. Without a calibration, or one that records no blur
/// (uniform fit, older file), the blur given or the default.
std::string choose_skin_blur(Scene& sc, const SceneFields::Options& options, const std::optional<PressureCalibration>& cal,
                             std::vector<std::string>& warnings) {
  const bool on_command_line = given_on_command_line(options, "assess.skin_blur_mm");
  const auto in_file = sc.file_keys.find("assess.skin_blur_mm");
  const std::string from = on_command_line ? "command line" : in_file != sc.file_keys.end() ? "scene file" : "default";
  if (!cal || !std::isfinite(cal->skin_blur_mm)) return from;
  double& blur = sc.assess.skin_blur_mm;
  if (from == "default") {
    blur = cal->skin_blur_mm;
    return "calibration";
  }
  if (std::abs(blur - cal->skin_blur_mm) > 1e-6) {
    const std::string given = on_command_line ? "--skin-blur-mm " + fixed(blur, 2)
                                              : sc.file.string() + ": line " + std::to_string(in_file->second) + ", key 'assess.skin_blur_mm' " + fixed(blur, 2);
    warnings.push_back("the skin's blur given (" + given + " mm) differs from the " + fixed(cal->skin_blur_mm, 2) + " mm the calibration " +
                       cal->path.string() + " was fitted with: its curve maps the signal to the pressure blurred by " +
                       fixed(cal->skin_blur_mm, 2) + " mm and the assessment undoes " + fixed(blur, 2) + " mm, so narrow places' peaks read " +
                       (blur > cal->skin_blur_mm ? "high" : "low") + "; leave assess.skin_blur_mm out to use the calibration's, or "
                       "calibrate again with calibrate-pressure --skin-blur-mm " + fixed(blur, 2));
  }
  return from;
}

}  // namespace

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
  if (sc.calibration.pressure.empty()) warn_or_refuse_kpa_thresholds(sc, o.options, p->warnings);
  if (!o.quiet) std::cerr << "clearfit assess: loading the part and tracing the refraction map\n";
  p->part = load_part_scene(sc, true, std::cerr);
  p->map = compute_part_map(*p->part, o.cache, &p->cache);
  InverseMapOptions iopt;
  iopt.texel_mm = sc.outputs.texel_mm;
  iopt.uv_min = p->part->chart->uv_min;
  iopt.uv_max = p->part->chart->uv_max;
  iopt.compute_errors = false;
  p->inverse = compute_inverse_map(p->map, iopt, &p->part->contact);
  p->inverse_options = iopt;
  p->baseline_part = sc.baseline.part;
  p->baseline_gap_mm = sc.baseline.gap();
  if (sc.baseline.part != BaselinePart::touching)
    p->baseline_rays = std::make_unique<BaselineRays>(p->part->trace_scene(), p->part->camera, p->part->cam_from_part,
                                                      p->part->map_options, sc.baseline.part, p->map);
  if (!o.quiet)
    std::cerr << "  map: " << p->map.stats.by_status[0] << " pixels see the skin (" << fixed(100 * p->map.stats.coverage)
              << " %), cache " << p->cache << "; chart " << p->inverse.width << " x " << p->inverse.height << " texels of "
              << fixed(sc.outputs.texel_mm, 3) << " mm\n";
  if (!sc.calibration.pressure.empty()) {
    p->calibration = read_pressure_calibration(sc.calibration.pressure);
    p->notes = check_calibration_matches(*p->calibration, sc.calibration.person, format_intrinsics_hash(p->part->camera.intrinsics_hash()));
  }
  p->skin_blur_from = choose_skin_blur(sc, o.options, p->calibration, p->warnings);
  AssessmentOptions& ao = p->options;
  ao.window_frames = cap.window_frames;
  ao.compensate_motion = cap.motion_compensation;
  ao.max_motion_px = cap.max_motion_px;
  ao.max_sums_mb = cap.max_mb;
  const AssessSection& as = sc.assess;
  ao.blanching = as.blanching();
  ao.thresholds_kpa = as.thresholds_kpa;
  ao.signal_thresholds = as.signal_thresholds;
  ao.signal_threshold_sigmas = as.significance_sigmas;
  ao.hysteresis_sigmas = as.hysteresis_sigmas;
  ao.lossy_outline_px = as.lossy_outline_px;
  ao.min_hotspot_area_mm2 = as.min_hotspot_area_mm2;
  ao.glare = as.glare.options;
  ao.phase_registration = as.phase_registration.options;
  ao.outline = as.outline.options;
  ao.vignetting = as.vignetting.options;
  ao.gap = sc.baseline.search;
  ao.timeseries = as.timeseries.options;
  ao.normalise_gains = as.normalise_exposure;
  p->sources = {cap.baseline, cap.worn, cap.both};
  return p;
}

}  // namespace clearfit::cli
