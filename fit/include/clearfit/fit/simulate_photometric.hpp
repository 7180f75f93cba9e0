#pragma once
// Photometric effects of real captures for `clearfit simulate` (issue 12,
// items 4 and 5): specular glare on the clear part, exposure and white-balance
// steps and drifts, and mains flicker whose frequency drifts. Each effect has
// its truth: the glare added per phase (linear, image-sized .npy) and the
// camera's gain per frame and channel (truth_gains.csv).
//
// Model. The camera sees lin_c = gain_c(t)·(skin_c + background + glare) +
// noise: glare is white light reflected by the part (added equally to R, G,
// B before the camera's gains); gain_c(t) = exposure(t)·wb_c(t)·flicker(t)
// multiplies everything the camera sees. Glare adds its own shot noise.
#include <clearfit/fit/simulate.hpp>

#include <array>
#include <filesystem>
#include <string>
#include <vector>

namespace clearfit::sim {

/// A specular highlight: a Gaussian blob of white light added in the image.
struct GlareBlob {
  enum class Phases { both, worn, baseline } phases = Phases::both;
  Vec2 center = Vec2(0.5, 0.5);  ///< relative to the image size (0..1)
  double sigma = 0.03;           ///< relative to the image width
  double peak = 0.3;             ///< linear, at the centre (1 = a white diffuser at full light)
  void validate() const;
};

/// A step of the camera's gains at a time of the capture (seconds from the
/// first frame of the time line, baseline then press).
struct GainStep {
  double t_s = 0;
  std::array<double, 3> gain{1, 1, 1};  ///< R, G, B factors applied from t_s on (exposure × white balance)
};

struct PhotometricEffects {
  std::vector<GlareBlob> glare;
  std::vector<GainStep> steps;
  std::array<double, 3> drift_per_s{0, 0, 0};  ///< relative gain drift per second, R, G, B
  double flicker_drift_hz_per_s = 0;           ///< the mains flicker's frequency drifts linearly (CameraSettings has amplitude, hz)
  bool any() const;  ///< anything beyond the renderer's defaults
  void validate() const;  ///< throws std::invalid_argument naming the field
};

/// Per frame: the camera's gain per channel (R, G, B; exposure × white
/// balance × flicker) and the glare image to add (CV_32F linear, or empty).
struct FrameLight {
  std::array<double, 3> gain{1, 1, 1};
  const cv::Mat* glare = nullptr;
};

/// The light of every frame of a time line and the glare images per phase.
class PhotometricSchedule {
 public:
  PhotometricSchedule(const PhotometricEffects& effects, const CameraSettings& camera, const Timeline& timeline,
                      cv::Size image);
  /// Frame k (0-based over baseline then press frames).
  FrameLight frame(int k) const;
  const cv::Mat& glare(bool worn) const { return worn ? glare_worn_ : glare_baseline_; }
  /// truth_gains.csv (frame, t_s, phase, gain_r, gain_g, gain_b), truth_glare_baseline.npy and
  /// truth_glare_worn.npy (float32 H × W, linear glare added) and truth_photometric.json. Atomic each.
  std::vector<std::string> write_truth(const std::filesystem::path& dir) const;

 private:
  PhotometricEffects fx_;
  CameraSettings cam_;
  Timeline tl_;
  cv::Mat glare_baseline_, glare_worn_;
};

}  // namespace clearfit::sim
