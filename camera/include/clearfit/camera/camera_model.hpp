#pragma once
// A camera: an mrcal lens model with its intrinsics, the imager size, and
// where the camera is (cam_from_part). Read from and written to mrcal's
// .cameramodel text format, so every mrcal tool works on it.
//
// Conventions (mrcal's): camera frame x right, y down, z forward; pixel (0,0)
// is the centre of the top-left pixel, so the imager spans [-0.5, W-0.5] x
// [-0.5, H-0.5]. Lengths in mm.
//
// Failures are values: a point that cannot be projected or a pixel that cannot
// be unprojected gives NaN in every component of its output (never an
// exception); test with `std::isnan(out.x())` or `!out.allFinite()`.
#include <clearfit/camera/pose.hpp>
#include <clearfit/geometry/mesh.hpp>  // Vec2, Vec3

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace clearfit {

struct CameraModel {
  /// Full mrcal lens model name, configuration included, e.g. "LENSMODEL_OPENCV8" or
  /// "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=30_Ny=20_fov_x_deg=120".
  /// Supported: every mrcal 2.2 model except CAHVORE (mrcal cannot unproject it).
  std::string lensmodel;
  /// fx, fy, cx, cy (pixels), then the distortion parameters in mrcal's order.
  std::vector<double> intrinsics;
  /// Larger imagers are refused when a model is read (no camera has one; the
  /// bound keeps a damaged imagersize from allocating gigabytes per pixel).
  static constexpr int kMaxImagerSide = 65536;
  static constexpr std::int64_t kMaxImagerPixels = 400'000'000;
  int width = 0;   ///< imager width, pixels
  int height = 0;  ///< imager height, pixels
  /// mrcal's rt_cam_ref with the part frame as the reference frame; t in mm.
  Rigid3 cam_from_part;
  /// The file it was read from (empty if built in memory); named in errors.
  std::filesystem::path path;

  /// Throws InputError naming `path` when the model is unusable: unknown or
  /// unsupported lens model, wrong intrinsics count, non-positive imager size or
  /// focal length, non-finite values.
  void validate() const;

  /// FNV-1a 64-bit hash of the lens model name, the intrinsics' bytes and the
  /// imager size: the cache key of everything that depends on the rays only
  /// (the pose is not part of it).
  std::uint64_t intrinsics_hash() const;

  /// Projects points given in the camera frame to pixels (mrcal_project).
  /// pixels.size() must equal points_in_cam.size() (std::invalid_argument).
  /// NaN for non-finite points, the origin, points with z <= 0 for models that
  /// cannot see behind the camera (pinhole, OpenCV, CAHVOR), and whatever mrcal
  /// cannot project. Points outside the imager still project (mrcal extrapolates).
  /// Parallel over chunks (TBB).
  void project(std::span<const Vec3> points_in_cam, std::span<Vec2> pixels) const;
  std::vector<Vec2> project(std::span<const Vec3> points_in_cam) const;
  Vec2 project(const Vec3& point_in_cam) const;

  /// Unit ray directions in the camera frame for pixels (mrcal_unproject, an
  /// iterative solve; the closed forms for PINHOLE, STEREOGRAPHIC, LONLAT,
  /// LATLON). rays.size() must equal pixels.size(). NaN where mrcal fails
  /// (e.g. far outside the imager of a strongly distorted lens). Parallel over
  /// chunks (TBB).
  void unproject(std::span<const Vec2> pixels, std::span<Vec3> rays) const;
  std::vector<Vec3> unproject(std::span<const Vec2> pixels) const;
  Vec3 unproject(const Vec2& pixel) const;
};

/// Reads an mrcal .cameramodel file (mrcal_read_cameramodel_file) and validates
/// it. Throws InputError naming the file (and the key, with its line where it
/// can be found) when the file is missing, is not a .cameramodel, names an
/// unknown or unsupported lens model, has the wrong number of intrinsics, etc.
/// Note: mrcal's parser itself prints a message to stderr on a malformed file.
CameraModel read_cameramodel(const std::filesystem::path& path);

/// Writes `model` as an mrcal .cameramodel text file at full precision (every
/// double round-trips exactly; mrcal's C writer keeps only 6 decimals),
/// atomically. The extrinsics are cam_from_part (the part is the reference).
/// Throws std::invalid_argument for an invalid model, InputError when the file
/// cannot be written.
void write_cameramodel(const CameraModel& model, const std::filesystem::path& path);

/// Unit ray directions for a grid of pixels, row-major.
/// Sample (i, j) is pixel (i * stride, j * stride); width = ceil(W / stride),
/// height = ceil(H / stride).
struct RayGrid {
  int width = 0;
  int height = 0;
  int stride = 1;
  std::uint64_t intrinsics_hash = 0;   ///< CameraModel::intrinsics_hash() of its camera
  std::vector<Vec3> rays;              ///< camera frame, unit; NaN where unprojection failed
  int exact_fallbacks = 0;             ///< samples the Newton route handed to mrcal_unproject

  const Vec3& at(int i, int j) const { return rays[static_cast<std::size_t>(j) * width + i]; }
  Vec2 pixel(int i, int j) const { return {double(i) * stride, double(j) * stride}; }
};

enum class UnprojectMethod {
  automatic,           ///< closed form where mrcal has one, else coarse_grid_newton
  exact,               ///< mrcal_unproject (or the closed form) at every sample
  coarse_grid_newton,  ///< see unproject_image()
};

struct UnprojectImageOptions {
  UnprojectMethod method = UnprojectMethod::automatic;
  int coarse_step_px = 16;          ///< spacing of the exactly unprojected coarse grid, pixels
  int max_newton_steps = 6;         ///< per sample; unconverged samples fall back to mrcal_unproject
  double tolerance_px = 1e-9;       ///< |project(ray) - pixel| accepted, pixels
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

/// The ray direction of every sample pixel of the imager, computed once per
/// camera (cache it by RayGrid::intrinsics_hash).
/// coarse_grid_newton: mrcal_unproject on a grid every coarse_step_px (plus the
/// last row and column), then each sample starts from the bilinear
/// interpolation of its cell's four rays and takes Newton steps on
/// mrcal_project in the plane tangent to that start (the 2x2 Jacobian from
/// mrcal's dq/dp at the start, reused for later steps), until the reprojection
/// error is below tolerance_px. Samples that do not converge, or whose cell
/// has a failed corner, are unprojected exactly. Measured on OPENCV8 (one
/// thread, CPU time): 640x480 69 ms vs 279 ms for mrcal_unproject everywhere,
/// 1920x1080 483 vs 1926 ms; largest angle between the two 2.7e-11 rad.
RayGrid unproject_image(const CameraModel& model, int stride = 1, const UnprojectImageOptions& options = {});

}  // namespace clearfit
