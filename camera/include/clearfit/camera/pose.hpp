#pragma once
// Rigid transforms (rotation + translation) and the small JSON pose file.
// Named by what they map: `cam_from_part` takes a point in the part frame to
// the camera frame, x_in_cam = cam_from_part.apply(x_in_part). Lengths in mm.
#include <Eigen/Core>
#include <array>
#include <filesystem>

namespace clearfit {

/// x_out = rotation * x_in + translation. `rotation` is orthonormal with
/// determinant +1 (not re-checked by the operations below); translation in mm.
struct Rigid3 {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  static Rigid3 identity() { return {}; }

  /// From mrcal's rt layout: r (Rodrigues vector: axis * angle, radians) then t.
  /// mrcal's t has whatever length unit the model uses; clearfit's
  /// .cameramodel files and pose files use millimetres.
  static Rigid3 from_rt(const std::array<double, 6>& rt);
  /// To mrcal's rt layout (r in radians, angle in [0, pi], then t).
  std::array<double, 6> to_rt() const;

  /// Maps a point: rotation * x + translation.
  Eigen::Vector3d apply(const Eigen::Vector3d& x) const { return rotation * x + translation; }
  /// Maps a direction (no translation).
  Eigen::Vector3d apply_direction(const Eigen::Vector3d& d) const { return rotation * d; }
  /// The inverse map: part_from_cam = cam_from_part.inverse().
  Rigid3 inverse() const;
};

/// Composition: (a_from_b * b_from_c).apply(x) == a_from_b.apply(b_from_c.apply(x)).
Rigid3 operator*(const Rigid3& a_from_b, const Rigid3& b_from_c);

/// Rotation matrix of a Rodrigues vector r (axis * angle, radians); exact
/// series near r = 0.
Eigen::Matrix3d rotation_from_rodrigues(const Eigen::Vector3d& r);
/// Rodrigues vector of a rotation matrix, angle in [0, pi] (via a unit
/// quaternion: stable near 0 and pi).
Eigen::Vector3d rodrigues_from_rotation(const Eigen::Matrix3d& rotation);

/// Reads a pose file {"schema":"clearfit.pose/1","cam_from_part":{"r":[3],"t":[3]},"units":"mm"}
/// (r in radians, t in mm) and returns cam_from_part.
/// Throws InputError naming the file and key (or line and column for JSON
/// syntax errors) when the file is missing, unreadable or malformed.
Rigid3 read_pose_json(const std::filesystem::path& path);

/// Writes cam_from_part in the format above, atomically (temporary file, then rename).
/// Throws InputError naming the path when it cannot be written.
void write_pose_json(const Rigid3& cam_from_part, const std::filesystem::path& path);

}  // namespace clearfit
