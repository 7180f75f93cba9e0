#pragma once
// Synthetic calibration sessions (issue: calibrating a real person): one video
// of the skin pressed 12–16 times by a clear flat indenter (a cylinder of
// radius a, seen through a flat clear slab or directly; Sneddon's flat-punch
// pressure, the skin's blur and blanching from skin_model.hpp), a force
// gauge's log with its own clock (offset, drift, noise, tare, overshoot, rest
// drift), and the truth.
//
// The indenter may instead be a clear sphere (sphere_radius_mm > 0): Hertz's
// pressure over a contact radius that grows with the force, its optics still
// those of the flat slab (the sphere's sag over the contact, a²/2R, is left out
// of the refraction).
//
// The camera looks along the indenter's axis (IndenterOptics). Each pixel
// sees one skin point (closed-form slab refraction); its albedo is the skin
// texture there; its drive is force(t)·IndenterProfile(punch, a, blur)(r)
// (the sphere: IndenterProfile(hertz, a(force(t)), blur));
// blood loss lags the drive (τ_on/τ_off); green radiance follows SKIN.md; the
// sensor adds Gaussian noise in 8-bit levels, then sRGB, 8 bits.
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/fit/indenter_field.hpp>
#include <clearfit/fit/simulate.hpp>
#include <clearfit/fit/skin_model.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace clearfit::sim {

/// Every parameter of a session, with its default (one home: the command binds these).
struct CalibrationSessionSpec {
  // camera and view
  int width = 160, height = 120;
  double focal_px = 600;             ///< pinhole camera written beside the video
  IndenterOptics optics{.distance_mm = 60, .slab_mm = 3};  ///< a 3 mm clear slab (its index: IndenterOptics)
  double indenter_radius_mm = 2.5;  ///< the flat punch's radius; a sphere's cap (the disc the presses are read over)
  double sphere_radius_mm = 0;       ///< > 0: a spherical indenter of this radius (Hertz), else the flat punch
  double e_star_kpa = 150;           ///< the skin's plane-strain modulus E* (the sphere's contact radius)
  Vec2 indenter_centre_mm = Vec2(0.6, -0.4);  ///< on the skin, from the optical axis
  double fps = 15;
  double exposure = 0.8;             ///< linear value of a white skin at full light
  double noise_levels = 1.0;         ///< sensor noise, 8-bit levels (linear, before sRGB)
  // presses (gauge clock)
  int presses = 14;
  double hold_s = 5, rest_min_s = 12, rest_max_s = 18, lead_s = 8;  // rests: the skin refills (τ_off) before its baseline
  double min_kpa = 4, max_kpa = 40;  ///< mean pressure of the presses (F/πa²; a sphere: over its contact disc), spread in random order
  double ramp_s = 0.3, overshoot = 0.08, overshoot_tau_s = 0.4;
  // gauge
  double gauge_hz = 50, offset_s = 3.7, drift_ppm = 300, force_noise_n = 0.003, tare_n = 0.05, rest_drift_n = 0.005;
  SkinParameters skin;
  VideoFormat format = VideoFormat::huffyuv;
  std::uint64_t seed = 1;
  /// Throws InputError naming the option (`--NAME`) and the rule.
  void validate() const;
};

struct SessionPressTruth {
  double start_s = 0, end_s = 0;  ///< gauge clock, force above zero
  double force_n = 0, mean_pressure_kpa = 0;
  double contact_radius_mm = 0;  ///< the punch's radius, or the sphere's Hertz contact radius
};

struct CalibrationSessionTruth {
  std::vector<SessionPressTruth> presses;
  EquivalentCalibration person;
  Vec2 indenter_centre_px = Vec2::Zero();
  int frames = 0;
  std::string video;  ///< file name in the output folder
};

/// The pinhole camera of the spec (z along the indenter's axis).
CameraModel session_camera(const CalibrationSessionSpec& spec);

/// Renders the session into `out`: the video (capture_name("session", format)),
/// force.csv (time_s, force_n on the gauge's clock), camera.cameramodel and
/// truth.json (schema clearfit.calibration-session-truth/1). `progress(done, total)` per frame.
CalibrationSessionTruth render_calibration_session(const CalibrationSessionSpec& spec, const std::filesystem::path& out,
                                                   const std::function<void(int, int)>& progress = {});

}  // namespace clearfit::sim
