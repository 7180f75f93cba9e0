#pragma once
// The part's pose from AprilTags fixed to the part or to a rigid fixture
// holding it: cam_from_part from the tags' corners seen in one or more images
// taken from one camera pose.
//
// Tag-layout file (`clearfit.tag-layout/1`, YAML; JSON is read too):
//   schema: clearfit.tag-layout/1
//   family: tag36h11
//   tags:
//     - id: 7
//       # corners in the part frame, mm, in AprilTag order for the upright tag:
//       # bottom-left, bottom-right, top-right, top-left (the outer corners of
//       # the black square)
//       corners_mm: [[0, 20, 0], [20, 20, 0], [20, 0, 0], [0, 0, 0]]
//     - id: 9
//       corners_mm: [...]
//       through_part: true   # seen through the part: never used (see below)
//
// Tags seen through the part itself are refracted, which would bias the pose:
// clearfit refuses them. A tag flagged `through_part: true` is never used (a
// note says so when it is seen); with the part's mesh at hand,
// tags_seen_through_part() finds unflagged ones and the CLI stops with an
// error naming them. Put pose tags on the fixture, beside the part.
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/detect.hpp>
#include <clearfit/camera/pose.hpp>

#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <string>
#include <vector>

namespace clearfit {

class RayIndex;

struct TagLayout {
  struct Tag {
    int id = -1;
    std::array<Eigen::Vector3d, 4> corners_mm;  ///< part frame, AprilTag order
    bool through_part = false;                  ///< refused: seen through the part
  };
  std::string family = "tag36h11";
  std::vector<Tag> tags;
  std::filesystem::path path;  ///< the file it came from (named in errors)

  /// The tag with this id, or nullptr.
  const Tag* find(int id) const;
};

/// Reads a tag-layout file. Throws InputError naming the file and key/tag
/// (with its line) for: a missing file, syntax errors, unknown keys, a schema
/// other than clearfit.tag-layout/1, an unknown family, duplicate ids, corners
/// that are not 4 finite points, or 4 points that are not a square (sides
/// differing by more than 5 %, or not planar to 2 % of the side: usually
/// corners out of order).
TagLayout read_tag_layout(const std::filesystem::path& path);

struct PoseOptions {
  int max_iterations = 50;      ///< Levenberg–Marquardt iterations
  double outlier_sigma = 5;     ///< drop corners whose residual exceeds this many sigma (one pass; 0: never)
  double min_outlier_px = 1.0;  ///< ... and this many pixels
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

/// A solved part pose and how well it is known.
struct PartPose {
  Rigid3 cam_from_part;
  double rms_px = 0;         ///< weighted RMS of the used corners' reprojection distances, px
  double noise_px = 0;       ///< per-coordinate corner noise (weight 1) from the residuals, dof-corrected, px
  int corners = 0;           ///< corners used
  int tags = 0;              ///< distinct tags used
  int images = 0;            ///< images that contributed corners
  int outliers = 0;          ///< corners dropped as outliers
  std::vector<int> tag_ids;  ///< the tags used, sorted
  /// 1-sigma uncertainty of cam_from_part (from (J^T W J)^-1 scaled by noise_px^2):
  /// translation along the camera axes (mm) and rotation about them (deg).
  Eigen::Vector3d sigma_translation_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d sigma_rotation_deg = Eigen::Vector3d::Zero();
  /// Covariance of (rotation perturbation about the camera axes in rad, translation in mm).
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  std::vector<std::string> notes;
};

/// Solves cam_from_part from tags detected in images taken from one camera
/// pose (`detections[i]` = the tags of image i). Corners are unprojected
/// through `camera` and a PnP seed is found (OpenCV SOLVEPNP_SQPNP on the
/// normalized undistorted points), then Levenberg–Marquardt minimises the
/// weighted pixel reprojection error through the full lens model (numeric
/// Jacobian of CameraModel::project), with one pass of outlier rejection.
/// Tags not in the layout are ignored; tags flagged through_part are refused
/// (note). Throws InputError (element "tags") when fewer than 4 corners of
/// usable tags remain, or no tag of the layout was seen.
PartPose solve_part_pose(const CameraModel& camera, const TagLayout& layout,
                         const std::vector<std::vector<DetectedTag>>& detections,
                         const PoseOptions& options = {});

/// Ids of used tags (`pose.tag_ids`) that the camera sees through the part: a
/// ray from the camera centre to one of their corners hits the part's mesh
/// (part frame, `part`) more than 0.01 mm before reaching the corner.
std::vector<int> tags_seen_through_part(const RayIndex& part, const PartPose& pose, const TagLayout& layout);

/// The pose as JSON text for people and scripts: {"schema": "clearfit.part-pose-report/1", ...}.
std::string part_pose_report_json(const PartPose& pose);

}  // namespace clearfit
