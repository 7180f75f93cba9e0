// clearfit simulate-session: a synthetic calibration session (video of the skin
// pressed by a clear flat indenter, the force gauge's log on its own clock, the
// truth), every parameter a command option with its default
// (sim::CalibrationSessionSpec).
#include <clearfit/output_folder.hpp>
#include <clearfit/cli/commands.hpp>

#include <clearfit/error.hpp>
#include <clearfit/fit/calibration_session.hpp>

#include <iostream>

namespace clearfit::cli {

Run add_simulate_session(CLI::App& app) {
  struct Opts {
    sim::CalibrationSessionSpec spec;
    std::string out, tone = "medium", format = "huffyuv";
    std::vector<int> size;
    bool quiet = false;
  };
  auto o = std::make_shared<Opts>();
  sim::CalibrationSessionSpec& s = o->spec;
  CLI::App* sub = app.add_subcommand(
      "simulate-session",
      "Synthetic calibration session: video of skin pressed by a clear flat indenter, a force log with its own clock, the truth");
  sub->add_option("--out", o->out, "Output folder (session video, force.csv, camera.cameramodel, truth.json)")->required();
  sub->add_option("--size", o->size, "Image width and height, px")->expected(2);
  sub->add_option("--focal-px", s.focal_px, "Pinhole focal length, px")->capture_default_str();
  sub->add_option("--distance-mm", s.optics.distance_mm, "Camera centre to skin, mm")->capture_default_str();
  sub->add_option("--slab-mm", s.optics.slab_mm, "Clear indenter thickness between camera and skin, mm (0: seen directly)")->capture_default_str();
  sub->add_option("--slab-ior", s.optics.slab_ior, "Its refractive index")->capture_default_str();
  sub->add_option("--indenter-radius-mm", s.indenter_radius_mm, "Flat cylindrical indenter radius a, mm (a sphere: its cap's radius)")->capture_default_str();
  sub->add_option("--sphere-radius-mm", s.sphere_radius_mm, "A spherical indenter of this radius, mm (Hertz contact; 0: the flat punch)")->capture_default_str();
  sub->add_option("--e-star-kpa", s.e_star_kpa, "The skin's plane-strain modulus E*, kPa (a sphere's contact radius)")->capture_default_str();
  sub->add_option("--fps", s.fps, "Video frame rate")->capture_default_str();
  sub->add_option("--noise-levels", s.noise_levels, "Sensor noise, 8-bit levels")->capture_default_str();
  sub->add_option("--presses", s.presses, "Number of presses")->capture_default_str();
  sub->add_option("--hold-s", s.hold_s, "Hold of each press, s")->capture_default_str();
  sub->add_option("--max-kpa", s.max_kpa, "Highest mean pressure F/(pi a^2), kPa (a sphere: over its contact disc; the presses spread from --min-kpa)")->capture_default_str();
  sub->add_option("--min-kpa", s.min_kpa, "Lowest mean pressure, kPa")->capture_default_str();
  sub->add_option("--overshoot", s.overshoot, "Force overshoot at each press's start (fraction)")->capture_default_str();
  sub->add_option("--gauge-hz", s.gauge_hz, "Force log sample rate")->capture_default_str();
  sub->add_option("--offset-s", s.offset_s, "Gauge clock offset: gauge time = (1 + drift) video time + offset")->capture_default_str();
  sub->add_option("--drift-ppm", s.drift_ppm, "Gauge clock drift, ppm")->capture_default_str();
  sub->add_option("--force-noise-n", s.force_noise_n, "Gauge noise, N")->capture_default_str();
  sub->add_option("--tare-n", s.tare_n, "Gauge reading at rest, N")->capture_default_str();
  sub->add_option("--rest-drift-n", s.rest_drift_n, "Slow drift of the gauge's rest reading, N")->capture_default_str();
  sub->add_option("--tone", o->tone, "Skin tone")->check(CLI::IsMember({"light", "medium", "dark"}))->capture_default_str();
  sub->add_option("--p50-kpa", s.skin.s50_kpa, "The person's logistic midpoint, kPa")->capture_default_str();
  sub->add_option("--width-kpa", s.skin.width_kpa, "The person's logistic width, kPa")->capture_default_str();
  sub->add_option("--beta", s.skin.beta, "The person's largest blood loss (y_max = k_G beta)")->capture_default_str();
  sub->add_option("--format", o->format, "Video format")->check(CLI::IsMember({"ffv1", "huffyuv", "mjpg", "png"}))->capture_default_str();
  sub->add_option("--seed", s.seed, "Random seed (press order, rests, noise)")->capture_default_str();
  sub->add_flag("--quiet", o->quiet, "No progress on stderr");

  return [o]() {
    sim::CalibrationSessionSpec spec = o->spec;
    if (o->size.size() == 2) spec.width = o->size[0], spec.height = o->size[1];
    spec.skin.tone = SkinTone::preset(o->tone);
    spec.format = sim::parse_video_format(o->format);
    spec.validate();
    int last = -1;
    StagedFolder staged(o->out);  // a killed run leaves the old folder (or none), never half a session
    const auto truth = sim::render_calibration_session(spec, staged.path(), [&](int done, int total) {
      if (!o->quiet && 10 * done / total != last) {
        last = 10 * done / total;
        std::cerr << "clearfit simulate-session: frame " << done << "/" << total << "\n";
      }
    });
    staged.commit();
    std::cout << "wrote into " << o->out << ": " << truth.video << " (" << truth.frames << " frames), force.csv, camera.cameramodel, truth.json\n"
              << "truth: offset " << spec.offset_s << " s, drift " << spec.drift_ppm << " ppm, " << truth.presses.size()
              << " presses; person p50 " << truth.person.p50_kpa << " kPa, width " << truth.person.width_kpa << " kPa, y_max "
              << truth.person.y_max << "\n";
    return 0;
  };
}

static const Registration registered{"simulate-session", 41, add_simulate_session};

}  // namespace clearfit::cli
