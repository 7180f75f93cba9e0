// clearfit simulate: synthetic captures of skin behind the part (baseline and
// worn videos), their ground truth, and calibration presses, from the scene
// file's common keys and its `simulation:` section.
#include <clearfit/cli/commands.hpp>
#include <clearfit/output_folder.hpp>
#include <clearfit/cli/part_setup.hpp>
#include <clearfit/cli/scene.hpp>
#include <clearfit/cli/simulate_photometric.hpp>

#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/pose.hpp>
#include <clearfit/error.hpp>
#include <clearfit/fit/simulate.hpp>
#include <clearfit/refraction/baseline_map.hpp>
#include <clearfit/refraction/map.hpp>

#include <clearfit/atomic_file.hpp>
#include <nlohmann/json.hpp>
#include <tbb/task_group.h>

#include <chrono>
#include <functional>
#include <optional>
#include <fstream>
#include <cmath>
#include <iostream>
#include <sstream>

namespace clearfit::cli {

namespace {


// The camera model at `scale` × its resolution (mrcal pixel centres: c' = s·(c + ½) − ½).
CameraModel scaled_camera(CameraModel cam, double s) {
  if (s == 1.0) return cam;
  cam.intrinsics[0] *= s, cam.intrinsics[1] *= s;
  cam.intrinsics[2] = s * (cam.intrinsics[2] + 0.5) - 0.5;
  cam.intrinsics[3] = s * (cam.intrinsics[3] + 0.5) - 0.5;
  cam.width = static_cast<int>(std::lround(cam.width * s));
  cam.height = static_cast<int>(std::lround(cam.height * s));
  cam.path.clear();
  return cam;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// truth.json's "preset": its name and the strength of every effect it sets, as
/// rendered (after the scene's own keys replaced the preset's).
void record_preset(const std::filesystem::path& truth_file, const SimulationSection& spec) {
  nlohmann::json t;
  {
    std::ifstream in(truth_file);
    t = nlohmann::json::parse(in);
  }
  const sim::CameraSettings& c = spec.camera;
  const sim::PhotometricEffects& fx = spec.photometric;
  nlohmann::json glare = nlohmann::json::array(), steps = nlohmann::json::array();
  for (const sim::GlareBlob& b : fx.glare)
    glare.push_back({{"center", {b.center.x(), b.center.y()}}, {"sigma", b.sigma}, {"peak", b.peak},
                     {"phases", b.phases == sim::GlareBlob::Phases::both ? "both" : b.phases == sim::GlareBlob::Phases::worn ? "worn" : "baseline"}});
  for (const sim::GainStep& s : fx.steps) steps.push_back({{"t_s", s.t_s}, {"gain", s.gain}});
  t["preset"] = {{"name", spec.preset},
                 {"motion", {{"step_px", c.motion_step_px}, {"drift_px_per_s", c.motion_drift_px_per_s}, {"tremor_px", c.motion_tremor_px},
                             {"tremor_hz", c.motion_tremor_hz}, {"rotation_deg", c.motion_rotation_deg}}},
                 {"flicker", {{"amplitude", c.flicker_amplitude}, {"hz", c.flicker_hz}, {"drift_hz_per_s", fx.flicker_drift_hz_per_s}}},
                 {"glare", glare},
                 {"exposure", {{"steps", steps}, {"drift_per_s", fx.drift_per_s}}},
                 {"video", {{"format", sim::to_string(spec.format)}, {"crf", spec.timeline.crf}}},
                 {"skin_motion", {{"slide_mm", {spec.skin_motion.slide_mm.x(), spec.skin_motion.slide_mm.y()}},
                                  {"bulge_mm", spec.skin_motion.bulge_mm}, {"bulge_width_mm", spec.skin_motion.bulge_width_mm}}},
                 {"note", "the strengths rendered: the preset's, replaced by the keys the scene gives"}};
  const sim::SkinMotion& m = spec.skin_motion;
  if (m.any())
    t["skin_motion"] = {{"slide_mm", {m.slide_mm.x(), m.slide_mm.y()}}, {"bulge_mm", m.bulge_mm}, {"bulge_width_mm", m.bulge_width_mm},
                        {"displacement_npy", "truth_displacement.npy"},
                        {"note", "the worn frames' skin texture displaced on the chart by d (mm, u v), the baseline's and the blanching not"}};
  write_file_atomically(truth_file, t.dump(2) + "\n");
}

/// The command line of `clearfit simulate`, and the scene it reads.
struct SimulateOptions {
  std::string scene_file, out, format;
  long long seed = -1;
  int crf = -1;
  double scale = 0;
  bool frames_only = false, no_presses = false, presses_only = false, quiet = false;
  Scene scene;
  SceneFields::Options options;
  CacheOptions cache;
};

using Say = std::function<void(const std::string&)>;

/// Reads the scene; its simulation: section with the command line's overrides (seed, format, crf, scale), checked.
SimulationSection simulation_spec(SimulateOptions& o) {
  read_scene(o.scene_file, o.scene, o.options);
  if (!o.scene.simulation)
    throw InputError(o.scene_file, "key 'simulation'", "missing: the scene has no simulation: section",
                     "add one (see the simulation keys in README.md)");
  SimulationSection spec = *o.scene.simulation;
  if (o.seed >= 0) spec.seed = static_cast<std::uint64_t>(o.seed);
  if (!o.format.empty()) spec.format = sim::parse_video_format(o.format);
  if (o.frames_only) spec.format = sim::VideoFormat::png;
  if (o.crf >= 0) spec.timeline.crf = o.crf;
  if (o.scale > 0) spec.scale = o.scale;
  if (!(spec.scale >= 0.05 && spec.scale <= 4)) throw InputError("", "--scale", "must be from 0.05 to 4");
  if (o.presses_only && !spec.presses)
    throw InputError(o.scene_file, "key 'simulation.presses'", "missing, but --presses-only was given");
  return spec;
}

/// simulation.pressure.map (a .npy on the chart grid at the field's texel_mm) as the field's user map;
/// InputError naming both shapes when they differ.
void read_pressure_map(SimulationSection& spec, const Chart& chart) {
  const cv::Mat m = sim::read_npy_2d(*spec.pressure_map);
  ChartField f;
  f.grid = ChartGrid::covering(chart.uv_min, chart.uv_max, spec.field.texel_mm);
  if (m.rows != f.grid.height || m.cols != f.grid.width) {
    std::ostringstream s;
    s << "the map is " << m.cols << " x " << m.rows << " (width x height); the chart grid at texel_mm "
      << spec.field.texel_mm << " is " << f.grid.width << " x " << f.grid.height;
    throw InputError(*spec.pressure_map, "shape", s.str(), "render it on the grid of truth_pressure.npy");
  }
  f.value.assign(m.begin<float>(), m.end<float>());
  spec.field.user_map = std::move(f);
}

/// What renders the frames from the skin's drive: the worn frames through the part's map (with the skin texture
/// displaced when the skin slid or bulged between the phases), and the not-worn frames through their own map when
/// the part is held off the skin or absent. Keeps references to `map` and `drive`, which must outlive it.
struct FrameRenderers {
  FrameRenderers(const LoadedPart& part, const RefractionMap& map, const ChartField& drive, const sim::PressureTruth& truth,
                 const SimulationSection& spec, const Say& say) {
    // The three renderers are built side by side (each is parallel inside, with serial stretches: the baseline
    // map's ray setup, the renderers' tables).
    tbb::task_group build;
    // The skin as it lies, through the part's map: the worn frames' unless the skin moved, the not-worn frames'
    // when the part touches then too (not built when no frame uses it: its texture and still view cost about a frame).
    if (!spec.skin_motion.any() || spec.baseline.part == BaselinePart::touching)
      build.run([&] { touching.emplace(map, drive, spec.skin, spec.camera, spec.seed); });
    if (spec.baseline.part != BaselinePart::touching)
      build.run([&] {
        baseline_map.emplace(compute_baseline_map(part.trace_scene(), part.camera, part.cam_from_part, part.map_options,
                                                  spec.baseline.part, spec.baseline.gap_mm, map));
        baseline_renderer.emplace(*baseline_map, drive, spec.skin, spec.camera, spec.seed);
      });
    if (spec.skin_motion.any())
      build.run([&] {
        skin_moved = sim::skin_displacement(spec.skin_motion, truth.pressure);
        moved_renderer.emplace(map, drive, spec.skin, spec.camera, spec.seed, &*skin_moved);
      });
    build.wait();
    if (baseline_map) {
      std::ostringstream b;
      b << "baseline: part " << to_string(spec.baseline.part) << ", skin " << spec.baseline.gap_mm << " mm beyond the contact surface, "
        << baseline_map->stats.by_status[0] << " pixels see it";
      say(b.str());
    }
  }
  FrameRenderers(const FrameRenderers&) = delete;
  FrameRenderers& operator=(const FrameRenderers&) = delete;
  const sim::CaptureRenderer& worn() const { return moved_renderer ? *moved_renderer : *touching; }
  /// The not-worn frames' renderer when it is not the worn one.
  const sim::CaptureRenderer* baseline() const {
    return baseline_renderer ? &*baseline_renderer : moved_renderer ? &*touching : nullptr;
  }

  std::optional<sim::CaptureRenderer> touching;           ///< through the part's map, the skin as it lies (when a frame uses it)
  std::optional<RefractionMap> baseline_map;              ///< the not-worn geometry's own map (held, absent)
  std::optional<sim::CaptureRenderer> baseline_renderer;  ///< through baseline_map
  std::optional<sim::SkinDisplacement> skin_moved;        ///< the worn frames' texture displacement on the chart
  std::optional<sim::CaptureRenderer> moved_renderer;     ///< through the part's map, the texture displaced
};

/// The frames of both phases written into `dir`, with progress by tenths.
sim::CaptureSummary render_frames(const FrameRenderers& renderers, const SimulationSection& spec, const cv::Size& image,
                                  const std::filesystem::path& dir, std::optional<sim::PhotometricSchedule>& photometry,
                                  const Say& say) {
  int last_decile = -1;
  if (spec.photometric.any()) photometry.emplace(spec.photometric, spec.camera, spec.timeline, image);
  sim::CaptureSummary cap = sim::render_captures(
      renderers.worn(), spec.skin, spec.timeline, spec.camera, spec.format, dir, spec.seed, [&](int done, int total) {
        const int decile = 10 * done / total;
        if (decile != last_decile) {
          last_decile = decile;
          say("frame " + std::to_string(done) + "/" + std::to_string(total));
        }
      }, photometry ? &*photometry : nullptr, renderers.baseline());
  cap.baseline = spec.baseline;
  return cap;
}

/// The ground truth beside the frames (truth.json with its inputs and preset, the pressure on the chart and the
/// vertices, the photometric effects, the skin's displacement) and the scaled camera; the names of the files written.
std::vector<std::string> write_capture_truth(const Scene& sc, const SimulationSection& spec, const LoadedPart& part,
                                             const RefractionMap& map, const sim::PressureTruth& truth,
                                             const sim::CaptureSummary& cap, const FrameRenderers& renderers,
                                             const std::optional<sim::PhotometricSchedule>& photometry,
                                             const std::filesystem::path& dir) {
  std::vector<std::string> written;
  std::vector<std::pair<std::string, std::string>> inputs{{"scene", sc.file.string()}, {"mesh", sc.part.mesh}, {"camera", sc.part.camera}};
  if (!sc.part.pose.empty()) inputs.emplace_back("pose", sc.part.pose);
  if (spec.pressure_map) inputs.emplace_back("pressure_map", *spec.pressure_map);
  if (spec.scale != 1.0) {
    if (part.projection_uncertainty) {  // kept, in the scaled camera's pixels
      ProjectionUncertainty u = *part.projection_uncertainty;
      for (double& px : u.px) px *= spec.scale;
      write_cameramodel(part.camera, u, dir / "camera.cameramodel");
    } else {
      write_cameramodel(part.camera, dir / "camera.cameramodel");
    }
    inputs.emplace_back("scaled_camera", "camera.cameramodel");
    written.push_back("camera.cameramodel");
  }
  sim::write_truth(dir, spec.field, truth, spec.skin, spec.camera, spec.timeline, cap, spec.format,
                   {map.width, map.height}, spec.seed, inputs);
  for (const auto& f : cap.files) written.push_back(f);
  for (const char* f : {"truth.json", "truth_pressure.npy", "truth_vertex_pressure.npy"}) written.emplace_back(f);
  if (photometry)
    for (const auto& f : photometry->write_truth(dir)) written.push_back(f);
  record_preset(dir / "truth.json", spec);
  if (renderers.skin_moved) {
    sim::write_displacement_npy(*renderers.skin_moved, dir / "truth_displacement.npy");
    written.emplace_back("truth_displacement.npy");
  }
  return written;
}

/// The frames' count and speed on `say`, and each true hotspot on stdout.
void print_capture_summary(const sim::CaptureSummary& cap, const RefractionMap& map, const SimulationSection& spec,
                           const sim::PressureTruth& truth, const Say& say) {
  const int frames = cap.baseline_frames + cap.press_frames + cap.release_frames;
  std::ostringstream s;
  s.precision(3);
  s << frames << " frames " << map.width << "x" << map.height << " (" << cap.baseline_frames << " baseline + "
    << cap.press_frames << " pressed"
    << (cap.release_frames > 0 ? " + " + std::to_string(cap.release_frames) + " after removal" : std::string()) << " at "
    << spec.timeline.fps << " fps): render " << cap.render_ms / frames
    << " ms/frame, waiting for the encoder " << cap.write_ms / frames << " ms/frame";
  say(s.str());
  for (std::size_t k = 0; k < truth.hotspots.size(); ++k) {
    const auto& h = truth.hotspots[k];
    std::ostringstream line;
    line.precision(3);
    line << "hotspot " << k + 1 << ": peak " << h.peak_kpa << " kPa, " << h.area_above_5_5_mm2 << " mm² >= 5.5 kPa at chart ("
         << h.centroid_uv_mm.x() << ", " << h.centroid_uv_mm.y() << ") mm";
    std::cout << line.str() << "\n";
  }
}

/// The captures: the part and its map as `clearfit map` reads them (the camera scaled), the true pressure field,
/// the frames of both phases and their ground truth, written into `dir`; the names of the files written.
std::vector<std::string> simulate_captures(const SimulateOptions& o, SimulationSection& spec, const std::filesystem::path& dir,
                                           const Say& say) {
  const Scene& sc = o.scene;
  if (spec.field.sources.empty() && !spec.pressure_map)
    throw InputError(o.scene_file, "key 'simulation.pressure'", "no pressure field: give sources or a map");
  const std::unique_ptr<LoadedPart> part = load_part_scene(sc, true, std::cerr);
  part->camera = scaled_camera(part->camera, spec.scale);
  if (spec.pressure_map) read_pressure_map(spec, *part->chart);
  sim::PressureTruth truth;
  try {
    truth = sim::make_pressure_truth(part->mesh, part->contact, *part->chart, spec.field);
  } catch (const InputError& e) {
    throw InputError(o.scene_file, "simulation.pressure", e.what());
  }
  auto t0 = std::chrono::steady_clock::now();
  std::string cache_state;
  const RefractionMap map = compute_part_map(*part, o.cache, &cache_state);
  say("refraction map " + std::to_string(map.width) + " x " + std::to_string(map.height) + ", " +
      std::to_string(map.stats.by_status[0]) + " pixels see the skin (" + std::to_string(seconds_since(t0)).substr(0, 4) +
      " s, cache " + cache_state + ")");
  t0 = std::chrono::steady_clock::now();
  const ChartField drive = skin_drive(spec.skin, truth.pressure);
  const FrameRenderers renderers(*part, map, drive, truth, spec, say);
  say("skin model and per-pixel terms ready (" + std::to_string(seconds_since(t0)).substr(0, 4) + " s)");
  std::optional<sim::PhotometricSchedule> photometry;
  const sim::CaptureSummary cap = render_frames(renderers, spec, cv::Size(map.width, map.height), dir, photometry, say);
  std::vector<std::string> written = write_capture_truth(sc, spec, *part, map, truth, cap, renderers, photometry, dir);
  print_capture_summary(cap, map, spec, truth, say);
  return written;
}

/// The calibration presses (presses.csv, presses-truth.json) written into `dir`; the names of the files written.
std::vector<std::string> simulate_presses(const SimulationSection& spec, const std::filesystem::path& dir) {
  const auto trials = sim::simulate_presses(spec.skin, spec.camera, *spec.presses, spec.seed);
  sim::write_presses_csv(trials, dir / "presses.csv");
  sim::write_presses_truth(dir / "presses-truth.json", spec.skin, spec.camera, *spec.presses, spec.seed);
  return {"presses.csv", "presses-truth.json"};
}

}  // namespace

Run add_simulate(CLI::App& app) {
  auto o = std::make_shared<SimulateOptions>();
  CLI::App* sub = app.add_subcommand("simulate", "Synthetic captures (baseline and worn videos) of skin behind the part, with ground truth and calibration presses");
  sub->add_option("scene", o->scene_file, "Scene file (YAML) with a simulation: section")->required();
  sub->add_option("--out", o->out, "Output folder (default: simulation.out, else captures/ beside the scene)");
  sub->add_option("--seed", o->seed, "Random seed (noise, motion, presses); default simulation.seed or 1");
  sub->add_option("--format", o->format, "Video format: huffyuv (lossless .mkv, default: fastest lossless to write and decode), ffv1 (lossless .mkv, smaller, 3x slower), mjpg (.avi, lossy: damages 0.5 % signals), png (frame folders), h264 (.mp4 as a phone films: libx264 at --crf, yuv420p, limited range, BT.709)")
      ->check(CLI::IsMember({"ffv1", "huffyuv", "mjpg", "png", "h264"}));
  sub->add_option("--crf", o->crf, "h264 only: libx264's constant rate factor, 0 (lossless) .. 51 (default 23; phones film at about 18-28)")
      ->check(CLI::Range(0, 51));
  sub->add_flag("--frames-only", o->frames_only, "Write folders of PNG frames instead of videos (same as --format png)");
  sub->add_option("--scale", o->scale, "Render at this fraction of the camera's resolution (writes the scaled camera.cameramodel)");
  sub->add_flag("--no-presses", o->no_presses, "Skip the calibration presses");
  sub->add_flag("--presses-only", o->presses_only, "Only the calibration presses (presses.csv, presses-truth.json)");
  sub->add_flag("--quiet", o->quiet, "No progress on stderr");
  o->options = add_scene_options(*sub, o->scene, kPartKeys);
  add_cache_options(*sub, o->cache);

  return [o]() {
    const auto t_start = std::chrono::steady_clock::now();
    SimulationSection spec = simulation_spec(*o);
    const std::filesystem::path out = !o->out.empty() ? std::filesystem::path(o->out)
                                      : !spec.out.empty() ? std::filesystem::path(spec.out)
                                                          : o->scene.file.parent_path() / "captures";
    // Everything goes into a staging folder that replaces `out` at the end (crash-safe, see output_folder.hpp);
    // --presses-only adds to the folder as it is.
    StagedFolder staged(out, o->presses_only);
    const Say say = [&](const std::string& s) {
      if (!o->quiet) std::cerr << "clearfit simulate: " << s << "\n";
    };
    std::vector<std::string> written;
    if (!o->presses_only) written = simulate_captures(*o, spec, staged.path(), say);
    if (!o->no_presses && spec.presses)
      for (auto& f : simulate_presses(spec, staged.path())) written.push_back(std::move(f));
    staged.commit();
    std::cout << "wrote into " << out.string() << ":";
    for (const auto& w : written) std::cout << " " << w;
    std::cout << " (" << std::to_string(seconds_since(t_start)).substr(0, 5) << " s)\n";
    return 0;
  };
}

static const Registration registered{"simulate", 40, add_simulate};

}  // namespace clearfit::cli
