#pragma once
// Synthetic captures of skin seen through the printed part, with ground truth:
// a pressure field on the contact chart → the skin model (skin_model.hpp) →
// radiance on the skin → through the part (the forward refraction map: each
// pixel's chart uv and Fresnel transmittance) → camera (fall-off, a fixed
// specular highlight, flicker, shot and read noise, sRGB, 8 bits) → video.
// Also the calibration presses that `clearfit calibrate-pressure` reads.
//
// Rendering method. Each pixel is the mean of n × n sub-pixel samples
// (supersample, default 2: offsets ±1/4 px); a sample's chart uv is
// interpolated bilinearly from the forward map's chart_uv at the four
// surrounding pixel centres, renormalised over the valid ones (a sample is
// skin when the valid weight is ≥ 1/2, else background). The skin is read from
// a fine chart texture (texture_mm) holding the albedo modulation m and the
// steady blood loss B_ss. Since D = ρ·exp(−k·a_p·g)·exp(k·B·s) with
// s = h(t)·(1 + a_p·g(t)) (h the press's lag), each pixel stores the moments
// Q_n = mean(m·B_ss^n), n = 0..3, once, and a frame evaluates
// exp(k·B·s) to third order (relative error < (k·B)^4/24 ≈ 3e-7): per frame
// only the blanching, pulse, flicker, noise and encoding are computed. With
// motion, the moments are recomputed at the shifted sample positions each
// frame (the image is re-rendered, not resampled).
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/fit/chart_field.hpp>
#include <clearfit/fit/skin_model.hpp>
#include <clearfit/refraction/baseline_map.hpp>
#include <clearfit/refraction/map.hpp>

#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace clearfit::sim {

struct FrameLight;           // simulate_photometric.hpp
class PhotometricSchedule;   // simulate_photometric.hpp

/// One pressure hotspot. Its centre is given on the chart (mm) or as a point
/// in the part frame (mm), which is moved to the nearest point of the contact
/// surface and taken to the chart there.
struct PressureSource {
  enum class Kind { gaussian, punch, hertz } kind = Kind::gaussian;
  std::string name;
  std::optional<Vec2> center_uv_mm;
  std::optional<Vec3> center_part_mm;
  double peak_kpa = 15, sigma_mm = 1.5;       ///< gaussian: peak·exp(−r²/(2σ²))
  double radius_mm = 2.5, rim_cap_ratio = 3;  ///< punch (Sneddon), capped at rim_cap_ratio·p_mean
  double force_n = 0.3;                       ///< punch and hertz
  double sphere_radius_mm = 10, e_star_kpa = 100;  ///< hertz
  /// Pressure (kPa) at distance r_mm from the centre.
  double pressure_kpa(double r_mm) const;
  std::string kind_name() const;
};

/// A field: the sum of the sources plus an optional user map on the same
/// chart grid (NaN in the user map counts as 0).
struct PressureFieldSpec {
  std::vector<PressureSource> sources;
  std::optional<ChartField> user_map;
  double texel_mm = 0.05;  ///< grid: ChartGrid::covering(chart.uv_min, chart.uv_max, texel_mm)
};

struct Hotspot {
  Vec2 centroid_uv_mm = Vec2::Zero();   ///< pressure-weighted over the ≥ 4.3 kPa region
  std::optional<Vec3> centroid_part_mm; ///< on the contact surface (none if the centroid falls off it)
  double peak_kpa = 0, area_above_5_5_mm2 = 0, area_above_4_3_mm2 = 0;
};

/// The truth: the pressure on the chart grid (kPa, NaN outside the contact
/// surface: texel centres outside every charted contact face), per mesh
/// vertex (NaN off the contact surface), the resolved source centres and the
/// hotspots (connected regions ≥ 4.3 kPa, 8-connected).
struct PressureTruth {
  ChartField pressure;
  std::vector<float> vertex_pressure;
  std::vector<Vec2> source_uv_mm;
  std::vector<std::optional<Vec3>> source_part_mm;
  std::vector<Hotspot> hotspots;
};

/// Builds the truth field. Throws InputError when a part-frame centre is
/// farther than 5 mm from the contact surface or a user map's grid differs
/// from the chart grid; std::invalid_argument on a broken chart.
PressureTruth make_pressure_truth(const Mesh& mesh, const ContactSurface& contact, const Chart& chart,
                                  const PressureFieldSpec& spec);

/// Nearest point of the contact surface to `point_in_part` (mm): the point,
/// its chart uv, its distance and the contact face it lies on. Brute force
/// over the contact faces.
struct SurfacePoint {
  Vec3 point = Vec3::Zero();
  Vec2 uv = Vec2::Zero();
  double distance_mm = 0;
  int face = -1;
};
SurfacePoint nearest_contact_point(const Mesh& mesh, const ContactSurface& contact, const Chart& chart,
                                   const Vec3& point_in_part);
/// The part-frame point at chart uv (the contact face containing it), if any.
std::optional<Vec3> part_point_at_uv(const Mesh& mesh, const Chart& chart, const Vec2& uv);

/// A source given in the part frame, placed on the 3D contact surface
/// (docs/pressure-sources.md): it presses along `normal`, the
/// outward normal of the contact face at its centre point. At a surface point
/// with face normal n it gives
///  - 0 on faces turned more than 60° from `normal` (a bump's wall),
///  - gaussian: the closed form at the 3D distance from the centre,
///  - punch, hertz (rigid indenters): the closed form at the distance from
///    the axis, on surface points within 10 % of the contact radius of the
///    indenter's plane; surfaces farther back (the plate around a bump) are
///    not reached: outside a flat punch the skin stays below its plane
///    (Sneddon's displacement (2d/π)·asin(a/r) < d).
struct SurfaceLoad {
  const PressureSource* source = nullptr;
  Vec3 centre = Vec3::Zero(), normal = Vec3::UnitZ();
  static SurfaceLoad at(const PressureSource& source, const SurfacePoint& centre, const Vec3& normal);
  double pressure_kpa(const Vec3& point, const Vec3& face_normal) const;
};

struct CameraSettings {
  double exposure = 1.0;          ///< linear gain: a white Lambertian skin at full light gives `exposure`
  double full_well_e = 2000;      ///< electrons at linear value 1 (shot noise)
  double read_noise_e = 3;        ///< electrons RMS
  double falloff = 0.25;          ///< illumination lost at the image corner (quadratic in radius)
  double specular_peak = 0.25;    ///< linear, added (white) at the highlight centre
  Vec2 specular_center = Vec2(0.3, 0.25);  ///< relative to the image size
  double specular_sigma = 0.03;   ///< relative to the image width
  double background = 0.05;       ///< linear level of pixels that see no skin (part edge, air)
  double flicker_amplitude = 0;   ///< relative light modulation (0: none)
  double flicker_hz = 100;        ///< mains flicker: 100 (50 Hz mains) or 120 (60 Hz)
  double motion_step_px = 0;      ///< random walk of the image: step std per frame and axis, px
  double motion_drift_px_per_s = 0;  ///< steady drift of the image, px/s (direction from the seed)
  double motion_tremor_px = 0;    ///< tremor: sinusoidal shake of this amplitude, px (direction from the seed)
  double motion_tremor_hz = 10;   ///< its frequency (physiological tremor: 8–12 Hz)
  double motion_rotation_deg = 0; ///< roll of the image about its centre, reached steadily by the last frame, degrees
  int supersample = 2;            ///< n × n samples per pixel (1..4)
  double texture_mm = 0.02;       ///< texel of the fine skin texture the samples read
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

/// How the not-worn capture is rendered: through its own refraction map
/// (refraction/baseline_map.hpp), the skin `gap_mm` beyond the contact
/// surface with the part held off it (or absent); touching renders it
/// through the worn map.
struct BaselineGeometry {
  BaselinePart part = BaselinePart::held;
  double gap_mm = 1.0;
  /// Throws std::invalid_argument unless 0 <= gap_mm <= 20 (ignored when touching).
  void validate() const;
};

/// Skin that slides and bulges between the phases (issue 12, item 2): the worn
/// frames show the skin's texture (ridges, mottling) displaced on the chart by
/// a smooth field, while the blanching stays where the part presses:
///   d(uv) = slide_mm + bulge_mm · (−∇P̃(uv)) / max|∇P̃|,
/// P̃ the true pressure blurred by a Gaussian of bulge_width_mm, so the skin
/// bulges outward around each pressed place, most at its steepest rim
/// (bulge_mm at the strongest place's, proportionally less at weaker ones).
/// The baseline frames show the skin undisplaced. Off (zero) by default.
struct SkinMotion {
  Vec2 slide_mm = Vec2::Zero();
  double bulge_mm = 0;
  double bulge_width_mm = 1.0;
  bool any() const { return slide_mm.squaredNorm() > 0 || bulge_mm != 0; }
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

/// The displacement of the worn skin on the chart (mm), on the pressure's grid.
struct SkinDisplacement {
  ChartField dx_mm, dy_mm;
  /// At chart uv: bilinear inside the grid, the nearest edge texel's value beyond it.
  Vec2 at(const Vec2& uv_mm) const;
};
/// d(uv) above from the true pressure (kPa, NaN off the contact surface: 0).
SkinDisplacement skin_displacement(const SkinMotion& motion, const ChartField& pressure_kpa);
/// truth_displacement.npy: float32 H x W x 2 (u, v in mm) on the pressure's chart grid. Atomic.
void write_displacement_npy(const SkinDisplacement& d, const std::filesystem::path& path);

struct Timeline {
  double fps = 60;
  double baseline_s = 4;  ///< not pressed
  double press_s = 3;     ///< pressed: B rises with τ_on from the first press frame
  /// After removal of the part (0: the capture ends pressed): B refills with τ_off. These
  /// frames follow the pressed ones in the same video (the worn one, or the single one), seen
  /// as the not-worn frames are (BaselineGeometry).
  double release_s = 0;
  bool single_video = false;  ///< one video holding both phases (else baseline and worn)
  int crf = 23;               ///< h264 only: libx264's constant rate factor (0 lossless … 51; phones film at about 18–28)
  int baseline_frames() const;
  int press_frames() const;
  int release_frames() const;
  /// Press and removal times (s, on the clock of the first frame, t = k/fps): the lag starts
  /// one frame period before the first pressed (first released) frame, so that frame already
  /// carries 1/fps of the response.
  double press_time_s() const;
  double release_time_s() const;
  void validate() const;
};

/// The press lag h(t) in [0, 1] (B = h·B_ss) at time t on the clock of the first
/// frame: 0 before the press, 1 − exp(−(t − t_press)/τ_on) while pressed, and after
/// removal h(t_release)·exp(−(t − t_release)/τ_off). t in seconds.
double press_lag(const Timeline& timeline, const SkinParameters& skin, double t_s);

/// A frame's motion of the image: the skin seen at reference pixel q is seen at
/// c + R(angle)·(q − c) + shift, c the image centre.
struct FrameMotion {
  Vec2 shift = Vec2::Zero();
  double angle_rad = 0;
  FrameMotion() = default;
  template <class Derived>  // a shift (any Eigen 2-vector expression) is a motion
  FrameMotion(const Eigen::MatrixBase<Derived>& s, double angle = 0) : shift(s), angle_rad(angle) {}  // NOLINT
  bool moved() const { return shift.squaredNorm() > 0 || angle_rad != 0; }
};

/// Per-pixel static terms, then frames. Not copyable (large); thread-safe render().
class CaptureRenderer {
 public:
  /// `map` must carry chart_uv and transmittance (traced with a chart); `drive`
  /// is skin_drive() of the pressure on the chart grid. `texture_shift`
  /// (optional): the skin's texture is read displaced by it (SkinMotion),
  /// the blanching is not.
  CaptureRenderer(const RefractionMap& map, const ChartField& drive, const SkinParameters& skin,
                  const CameraSettings& camera, std::uint64_t seed, const SkinDisplacement* texture_shift = nullptr);
  CaptureRenderer(const CaptureRenderer&) = delete;
  CaptureRenderer& operator=(const CaptureRenderer&) = delete;

  /// One 8-bit BGR frame (CV_8UC3) at time t_s with press lag h in [0, 1]
  /// (B = h·B_ss), image motion (px and rad: the skin moves by +shift in the image, turned about the centre) and
  /// frame number (seeds the noise). `light` (optional): the camera's gains and
  /// the glare of this frame, replacing the flicker (simulate_photometric.hpp).
  cv::Mat render(double t_s, double press_lag, const FrameMotion& motion, std::uint64_t frame,
                 const FrameLight* light = nullptr) const;
  /// The noiseless linear green of a pixel (for tests), no shift, no flicker.
  double linear_green(int x, int y, double t_s, double press_lag) const;
  int width() const { return width_; }
  int height() const { return height_; }
  long long skin_pixels() const { return skin_pixels_; }
  double setup_ms() const { return setup_ms_; }

 private:
  struct Pixel {
    float q[4];      ///< moments of m·B_ss^n over the samples (background samples count 0)
    float gain;      ///< exposure·fall-off·transmittance
    float additive;  ///< specular + background (linear)
    float sigma[3];  ///< noise std (linear) per channel
  };
  /// The moments of the pixel centred at (x, y) of the still view; returns how many of its
  /// samples fall on skin (their taps' weight on valid pixels at least one half).
  int moments(double x, double y, float q[4]) const;
  /// Into `out`: the pixel whose centre lies at (px, py) of the still view (a moved frame's pixel,
  /// mapped back); skin = false: a pixel known to see no skin (no sampling).
  void static_pixel(double px, double py, Pixel& out, bool skin = true) const;
  /// static_pixel(q, false) of the moved frame's row pixels x0..x1 − 1 (row offset uy from the centre less the shift,
  /// the shift's x, the turn's cos and sin) into out[0 .. x1 − x0).
  void background_pixels(int x0, int x1, double uy, double shift_x, double ca, double sa, Pixel* out) const;

  const RefractionMap& map_;
  SkinParameters skin_;
  CameraSettings cam_;
  std::uint64_t seed_;
  int width_, height_;
  ChartGrid tex_grid_;
  std::vector<std::array<float, 2>> tex_mb_;  ///< fine texture: modulation and steady blood loss per texel
  /// A map pixel as the samples read it: chart uv (NaN where it has none), transmittance, valid; `cell`: the
  /// taps of the cell it starts (it, right, below, below right) are all valid with chart uv and no seam between them.
  struct Tap {
    float u, v, transmittance;
    bool valid, cell;
  };
  /// The bilinear read of the taps around a sub-pixel sample at (sx, sy); false for a background sample.
  struct SampleRead {
    double u, v, transmittance;
  };
  bool read_taps(double sx, double sy, int& skin, SampleRead& out) const;
  void add_texture_sample(const SampleRead& r, double acc[4]) const;
  /// x / n² for n × n samples per pixel: a product by 1/n² when n² is a power of two (the same result).
  double divide_by_samples(double x) const {
    const int n2 = cam_.supersample * cam_.supersample;
    return (n2 & (n2 - 1)) == 0 ? x * (1.0 / n2) : x / n2;
  }
  bool add_cell_pair(double sx0, double sx1, double sy, double acc[4]) const;
  std::vector<Tap> taps_;
  std::vector<Pixel> pixels_;
  std::vector<std::pair<int, int>> row_span_;  ///< per image row: first and last valid map pixel (1, 0 if none)
  std::vector<float> noise_pool_;
  std::vector<std::uint8_t> srgb_lut_;
  long long skin_pixels_ = 0;
  double setup_ms_ = 0;
};

/// Video outputs. huffyuv (.mkv) and ffv1 (.mkv) are lossless through
/// OpenCV 4.6's FFmpeg backend (Debian 12); mjpg (.avi, OpenCV's own MJPEG
/// writer at quality 100) is lossy; png writes a folder of frames
/// (frame_00000.png, ...). Measured on simulated 1080p skin (CPU ms per frame
/// to decode, MB per frame): huffyuv 40, 4.3; ffv1 140, 3.3; png 78, 3.7;
/// mjpg 10, 0.3 but it shifts a 0.4 % blanching signal by ~30 % after
/// averaging. huffyuv is the default. h264 (.mp4) films as a phone does: libx264
/// through FFmpeg's libraries at Timeline::crf (preset fast, 1 s key-frame
/// interval), yuv420p, limited range, tagged BT.709.
enum class VideoFormat { ffv1, huffyuv, mjpg, png, h264 };
VideoFormat parse_video_format(const std::string& name);  ///< throws std::invalid_argument
std::string to_string(VideoFormat format);
/// The file or folder name of a capture called `stem` ("baseline", "worn", "capture").
std::string capture_name(const std::string& stem, VideoFormat format);

/// Writes frames to a video (or PNG folder) atomically: into a temporary
/// beside `path`, renamed on finish(). Throws InputError when the writer
/// cannot be opened or a write fails.
class CaptureWriter {
 public:
  CaptureWriter(const std::filesystem::path& path, VideoFormat format, double fps, cv::Size size, int crf = 23);
  ~CaptureWriter();
  void write(const cv::Mat& frame);
  void finish();
  int frames() const { return frames_; }

 private:
  std::filesystem::path path_, temp_;
  VideoFormat format_;
  struct Video;  // cv::VideoWriter (videoio is private to the module)
  std::unique_ptr<Video> video_;
  struct Libav;  // H.264 (libx264) and HuffYUV through FFmpeg's libraries
  std::unique_ptr<Libav> libav_;
  int frames_ = 0;
  bool done_ = false;
};

struct CaptureSummary {
  std::vector<std::string> files;       ///< file or folder names written, in order
  int baseline_frames = 0, press_frames = 0, release_frames = 0;
  int press_start_frame = 0;            ///< first pressed frame (in the single video, or 0 in worn)
  std::vector<Vec2> shift_px;           ///< per frame (baseline then press)
  std::vector<double> angle_rad;        ///< per frame: rotation about the image centre
  double render_ms = 0, write_ms = 0;
  BaselineGeometry baseline{BaselinePart::touching, 0.0};  ///< how the baseline frames were rendered (set by the caller)
};

/// Renders the time line into `out_dir`: baseline + worn (or capture) videos.
/// `progress(done, total)` is called after each frame (may be empty); `photometry` (optional)
/// gives each frame's gains and glare (simulate_photometric.hpp); `baseline` (optional) renders
/// the not-worn frames (before the press, and after the part's removal) through their own map
/// (BaselineGeometry), else `renderer` renders every frame.
CaptureSummary render_captures(const CaptureRenderer& renderer, const SkinParameters& skin, const Timeline& timeline,
                               const CameraSettings& camera, VideoFormat format, const std::filesystem::path& out_dir,
                               std::uint64_t seed, const std::function<void(int, int)>& progress = {},
                               const PhotometricSchedule* photometry = nullptr, const CaptureRenderer* baseline = nullptr);

/// Calibration presses through the forward model (no images): a flat
/// cylindrical indenter of each diameter at `levels` mean pressures evenly
/// over [0, max_kpa], `repetitions` times. The signal is the feature
/// y = ln[(G/G0)/(G_ref/G_ref0)] averaged over the indenter disc, with the
/// noise of a measured region: per-pixel sensor noise of the skin tone's green
/// (CameraSettings) averaged over the disc's pixels (px_per_mm) and `frames`
/// frames of each phase, plus a per-trial relative jitter (trial_jitter) of
/// the physiological response. profile sneddon: the disc carries Sneddon's
/// pressure (capped at 3·p_mean) through the skin drive (blur, von Mises mix),
/// so y(mean pressure) departs from the logistic at the rim as in the study;
/// uniform: y = k_G·β·Ψ(p_mean) exactly (plus noise).
struct PressOptions {
  std::vector<double> diameters_mm{3.0};
  int levels = 9;
  double max_kpa = 30;
  int repetitions = 3;
  enum class Profile { sneddon, uniform } profile = Profile::sneddon;
  int frames = 100;
  double px_per_mm = 20;
  double trial_jitter = 0.05;  ///< relative SD of a trial's response
  double offset_sd = 0.001;    ///< additive SD of a trial's signal (baseline drift between phases)
  /// Ring width of each press's radial signal profile (the rings `clearfit presses`
  /// measures: 0 to the radius + 1 mm); 0 writes no profiles. Profiles are written
  /// for the sneddon profile only (a uniform disc has no field to resolve).
  double ring_mm = 0.2;
  void validate() const;
};
struct PressTrial {
  int trial = 0;
  double diameter_mm = 0, force_n = 0, mean_pressure_kpa = 0, signal = 0;
  double signal_noiseless = 0;
  std::vector<double> ring_edges_mm, ring_signal;  ///< radial profile (empty: none)
};
std::vector<PressTrial> simulate_presses(const SkinParameters& skin, const CameraSettings& camera,
                                         const PressOptions& options, std::uint64_t seed);
/// presses.csv: header trial,indenter_diameter_mm,force_n,mean_pressure_kpa,signal, and
/// ring_edges_mm,ring_signal (';'-separated) when the trials carry profiles. Atomic.
void write_presses_csv(const std::vector<PressTrial>& trials, const std::filesystem::path& path);

/// Writes truth.json (schema clearfit.simulation-truth/1), truth_pressure.npy
/// (float32 chart grid, kPa, NaN off the contact surface) and
/// truth_vertex_pressure.npy (float32 per mesh vertex) into `dir`.
/// `inputs` (name → path) are recorded as given.
void write_truth(const std::filesystem::path& dir, const PressureFieldSpec& spec, const PressureTruth& truth,
                 const SkinParameters& skin, const CameraSettings& camera, const Timeline& timeline,
                 const CaptureSummary& captures, VideoFormat format, cv::Size image_size, std::uint64_t seed,
                 const std::vector<std::pair<std::string, std::string>>& inputs);
/// Pearson correlation of an assessment's per-vertex pressure (vertices.csv, pressure_kpa) with the
/// simulation's truth (truth_vertex_pressure.npy), over the contact vertices seen whose truth is finite; NaN
/// with fewer than 3 or no spread. `count` (optional) receives how many vertices were compared.
double vertex_pressure_pearson(const std::filesystem::path& vertices_csv, const std::filesystem::path& truth_vertex_npy,
                               int* count = nullptr);
/// presses-truth.json (schema clearfit.presses-truth/1): the skin's parameters,
/// the equivalent calibration, the options and the signal noise.
void write_presses_truth(const std::filesystem::path& path, const SkinParameters& skin, const CameraSettings& camera,
                         const PressOptions& options, std::uint64_t seed);

/// NumPy .npy float32 writer (C order), atomic; and a reader of 2-D float32 /
/// float64 arrays (InputError naming the file when it is not one).
void write_npy_float32(const std::filesystem::path& path, const std::vector<std::size_t>& shape, const float* data);
cv::Mat read_npy_2d(const std::filesystem::path& path);

}  // namespace clearfit::sim
