#pragma once
// Calibration sessions, the image side: from a recording of the skin pressed by
// a clear flat indenter and the force gauge's log (force_log.hpp) to the
// calibration presses that `calibrate-pressure` fits, each with its signal
// field under the indenter, radially resolved in mm on the skin.
//
// 1. The video is read once; its green channel (8-bit) is kept per frame.
// 2. The indenter is found (unless given): the image blocks whose green varies
//    most over the session once the frame's common change is removed (the skin
//    under the indenter blanches with every press; elsewhere only noise,
//    pulse and exposure); later refined to the centroid, on the skin, of the
//    blanching summed over the presses.
// 3. The clocks are aligned (align_clocks) on the indenter area's signal
//    y(t) = ln(G/G̃) − ln(G_ref/G̃_ref) (G̃: the median over the session; ref:
//    the skin 2–4 mm beyond the indenter's rim).
// 4. Per press: y = ln(Ḡ_hold/Ḡ_rest) − ln(Ḡ_ref,hold/Ḡ_ref,rest) per pixel
//    (linear green averaged over the settled hold and over that press's own
//    rest), then the mean over the indenter disc (`signal`) and over rings
//    of ring_mm on the skin (pixels mapped through the slab, IndenterOptics).
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/fit/force_log.hpp>
#include <clearfit/fit/indenter_field.hpp>

#include <opencv2/core.hpp>

#include <optional>
#include <string>
#include <vector>

namespace clearfit {

struct SessionOptions {
  double indenter_radius_mm = 0;     ///< required (> 0)
  IndenterOptics optics;
  std::optional<Eigen::Vector2d> centre_px;  ///< the indenter's centre in the image; found when absent
  double fps = 0;                    ///< 0: the video's own (required for frame folders)
  double ring_mm = 0.2;              ///< ring width of the radial profile
  double profile_margin_mm = 1.0;    ///< the profile runs to a + this
  int block_px = 8;                  ///< blocks of the indenter search
  PressSegmentation segmentation;
  AlignmentOptions alignment;
  /// Throws InputError naming the option.
  void validate() const;
};

struct SessionPress {
  ForcePress force;                  ///< gauge clock
  double hold_start_s = 0, hold_end_s = 0, rest_start_s = 0, rest_end_s = 0;  ///< video clock
  int hold_frames = 0, rest_frames = 0;
  double signal = 0;                 ///< y averaged over the indenter disc
  std::vector<double> ring_signal;   ///< y per ring (NaN where a ring holds no pixel)
  int log_line = 0;                  ///< line of the press's start in the force log
};

struct SessionAnalysis {
  std::filesystem::path video, force_log;
  double fps = 0;
  int frames = 0, width = 0, height = 0;
  double tare_n = 0;
  ClockAlignment clock;
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero(), centre_mm = Eigen::Vector2d::Zero();
  bool centre_found = false;          ///< found in the image (else given)
  double mm_per_px = 0;               ///< at the indenter's centre, on the skin
  std::vector<double> ring_edges_mm;  ///< ring k: [edges[k], edges[k+1])
  std::vector<double> time_s, trace;  ///< video clock: the indenter area's signal
  std::vector<double> force_time_s, force_n;  ///< the log on the video clock
  std::vector<SessionPress> presses;
  cv::Mat blanching;                  ///< CV_32F: y per pixel summed over the presses
  std::vector<std::string> warnings, notes;
};

/// Runs steps 1–4. Throws InputError naming the file and line (force log),
/// the frame (video) or the option: log errors (read_force_log), no presses,
/// fewer than 4 presses (the logistic has 3 parameters), a video whose size
/// differs from the camera's, an ambiguous alignment, a press outside the
/// recording (the recording shorter than the log), a saturated or
/// over-exposed indenter area (more than 1 % of its pixels at 0 or 255).
SessionAnalysis analyse_session(const std::filesystem::path& video, const std::filesystem::path& force_log,
                                const CameraModel& camera, const SessionOptions& options);

}  // namespace clearfit
