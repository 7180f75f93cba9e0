#pragma once
// The pose file with its uncertainty: clearfit.pose/1 (pose.hpp) plus the
// optional covariance `clearfit pose` writes, read back by the commands that
// take a pose (the assessment turns it into a σ of where on the skin each
// texel lies).
#include <clearfit/camera/pose.hpp>

#include <optional>

namespace clearfit {

/// Covariance of a pose: (rotation perturbation about the camera axes in rad, translation in mm),
/// the perturbation cam_from_part' = (exp(δθ) R, t + δt) (camera/tag_pose.hpp).
using PoseCovariance = Eigen::Matrix<double, 6, 6>;

/// A pose file's content: the pose and, when the file carries it, its covariance.
struct PoseFile {
  Rigid3 cam_from_part;
  std::optional<PoseCovariance> covariance;
};

/// Reads a pose file (read_pose_json) with its optional uncertainty keys: "covariance" (6×6, as
/// PoseCovariance) and "sigma": {"rotation_deg": [3], "translation_mm": [3]} (1-σ about / along the
/// camera axes; read as independent when there is no "covariance"). Throws InputError naming the file
/// and key when a σ or the covariance is malformed (not finite, negative, asymmetric).
PoseFile read_pose_file(const std::filesystem::path& path);

/// write_pose_json with "sigma" (√ of the diagonal, rotation in degrees) and "covariance".
void write_pose_json(const Rigid3& cam_from_part, const std::filesystem::path& path, const PoseCovariance& covariance);

}  // namespace clearfit
