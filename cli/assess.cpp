// clearfit assess: the fit assessment of a scene — captures → blanching →
// pressure → hotspots → heatmap on the mesh and the report.
#include <clearfit/cli/assess_setup.hpp>
#include <clearfit/cli/commands.hpp>
#include <clearfit/cli/provenance.hpp>

#include <chrono>
#include <future>
#include <clearfit/error.hpp>
#include <clearfit/fit/assessment.hpp>
#include <clearfit/reports/assessment_report.hpp>
#include <clearfit/reports/report_html.hpp>
#include <clearfit/refraction/inverse_map.hpp>
#include <cmath>
#include <clearfit/atomic_file.hpp>
#include <clearfit/npy.hpp>
#include <clearfit/output_folder.hpp>
#include <fstream>
#include <iostream>

namespace clearfit::cli {
namespace {

namespace fs = std::filesystem;

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
    // The inputs' SHA-256 for the report, on a thread of its own while the captures are read (about
    // 0.8 s of CPU for the sample's 1.3 GB of lossless video, which would otherwise follow the assessment).
    const CapturesSection& cap = sc.captures;
    std::future<std::vector<ReportInput>> hashes = std::async(std::launch::async, [named = std::vector<std::pair<std::string, std::string>>{
        {"scene", o->scene_file}, {"mesh", sc.part.mesh}, {"camera", sc.part.camera}, {"pose", sc.part.pose}, {"baseline", cap.baseline},
        {"worn", cap.worn}, {"capture", cap.both}, {"calibration", sc.calibration.pressure}}] {
      std::vector<ReportInput> inputs;
      for (const auto& [role, path] : named)
        if (!path.empty()) inputs.push_back({role, path, sha256_of_path(path)});
      return inputs;
    });
    StagedFolder staged(sc.outputs.folder);
    p->options.progress = progress_printer(o->quiet);
    const AssessmentScene scene = p->view();
    const LoadedPart* part = p->part.get();
    const RefractionMap& map = p->map;
    const auto& calibration = p->calibration;
    Assessment a = [&] {
      try {
        return assess_captures(scene, p->sources, calibration, p->options);
      } catch (...) {
        if (!o->quiet) std::cerr << "\n";  // the progress line it interrupts ends before the error is printed
        throw;
      }
    }();
    a.warnings.insert(a.warnings.begin(), p->warnings.begin(), p->warnings.end());
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
    ctx.inputs = hashes.get();
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
                   {"skin_blur_mm", sc.assess.skin_blur_mm},
                   {"skin_blur_from", p->skin_blur_from},
                   {"thresholds_kpa", sc.assess.thresholds_kpa},
                   {"signal_thresholds", sc.assess.signal_thresholds},
                   {"significance_sigmas", sc.assess.significance_sigmas},
                   {"hysteresis_sigmas", sc.assess.hysteresis_sigmas},
                   {"min_hotspot_area_mm2", sc.assess.min_hotspot_area_mm2},
                   {"glare_mask", sc.assess.glare.options.enabled},
                   {"glare_margin_px", sc.assess.glare.options.margin_px},
                   {"phase_registration", sc.assess.phase_registration.options.enabled},
                   {"phase_registration_smoothing_mm", sc.assess.phase_registration.options.smoothing_mm},
                   {"outline", sc.assess.outline.options.enabled},
                   {"exposure_normalisation", sc.assess.normalise_exposure},
                   {"timeseries", sc.assess.timeseries.options.enabled},
                   {"timeseries_cell_px", sc.assess.timeseries.options.cell_px},
                   {"timeseries_max_mb", sc.assess.timeseries.options.max_mb},
                   {"baseline_part", to_string(sc.baseline.part)},
                   {"baseline_gap_mm", sc.baseline.gap_mm},
                   {"baseline_max_shift_px", sc.baseline.search.max_shift_px},
                   {"baseline_gap_sigma_in_signal", sc.baseline.search.sigma_in_signal},
                   {"person", sc.calibration.person}};
    for (const auto& n : notes) std::cerr << "clearfit: note: " << n << "\n";
    ctx.run_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    write_assessment_outputs(a, scene, part->normals, ctx, staged.path());
    std::string html_note;
    if (!o->no_html) {
      try {
        const auto result = reports::write_report_html(staged.path());
        for (const auto& n : result.notes) std::cerr << "clearfit: note: " << n << "\n";
      } catch (const OutputError&) {
        throw;  // the disk refused it: the run's error, not a missing optional page
      } catch (const InputError& e) {
        html_note = std::string("report.html not written: ") + e.what();
      }
    }
    staged.commit();

    std::cout << "assessed " << ctx.mesh_name << ": " << fixed(a.coverage.seen_area_mm2, 0) << " of " << fixed(a.coverage.contact_area_mm2, 0)
              << " mm² of the contact surface seen; signal noise " << fixed(a.signal.noise_sigma, 4) << "\n";
    if (a.calibrated)
      std::cout << "pressure: peak " << fixed(a.peak_kpa) << " kPa, mean " << fixed(a.mean_kpa) << " kPa over the seen skin\n";
    std::cout << a.hotspots.size() << (a.hotspots.size() == 1 ? " hotspot" : " hotspots") << "\n";
    for (const Hotspot& h : a.hotspots) {
      // A peak without σ lies beyond the calibration's range: it is a lower bound.
      const std::string unit = !a.calibrated                   ? ""
                               : std::isfinite(h.peak_sigma) ? " ± " + fixed(h.peak_sigma) + " kPa"
                                                             : " kPa or more (beyond the calibration's range)";
      std::cout << "  #" << h.id << ": peak " << fixed(h.peak, a.calibrated ? 1 : 4) << unit << ", area";
      for (const HotspotLevel& l : h.levels)
        std::cout << (&l == &h.levels.front() ? " " : ", ") << fixed(l.area_mm2, 2) << " mm² >= "
                  << (a.calibrated ? fixed(l.threshold) + " kPa" : fixed(l.threshold, 4));
      std::cout << ", centroid (" << fixed(h.centroid_mm.x(), 2) << ", " << fixed(h.centroid_mm.y(), 2) << ", " << fixed(h.centroid_mm.z(), 2)
                << ") mm";
      if (h.unseen_area_mm2 > 0) std::cout << ", " << fixed(h.unseen_area_mm2, 2) << " mm² unseen beside it";
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

}  // namespace clearfit::cli
