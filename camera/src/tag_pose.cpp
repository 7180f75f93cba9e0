// The part's pose from AprilTags with known corners in the part frame.
#include <clearfit/camera/tag_pose.hpp>
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>
#include <clearfit/yaml_key.hpp>
#include <clearfit/geometry/ray_index.hpp>

#include "apriltag_family_internal.hpp"

#include <yaml-cpp/yaml.h>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <unsupported/Eigen/NonLinearOptimization>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <sstream>

namespace clearfit {

namespace {

std::string line_of(const YAML::Node& n) { return "line " + std::to_string(n.Mark().line + 1); }

struct Correspondence {
  Eigen::Vector3d point_in_part;
  Eigen::Vector2d pixel;
  double weight;
  int tag, image;
};

Eigen::Matrix3d exp_so3(const Eigen::Vector3d& w) { return rotation_from_rodrigues(w); }

/// Weighted pixel residuals (2 per correspondence) of a pose.
Eigen::VectorXd residuals(const CameraModel& cam, const std::vector<Correspondence>& c,
                          const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
  std::vector<Vec3> p(c.size());
  for (std::size_t i = 0; i < c.size(); ++i) p[i] = R * c[i].point_in_part + t;
  const std::vector<Vec2> q = cam.project(std::span<const Vec3>(p));
  Eigen::VectorXd r(2 * c.size());
  for (std::size_t i = 0; i < c.size(); ++i) r.segment<2>(2 * i) = c[i].weight * (q[i] - c[i].pixel);
  return r;
}

/// The pose's weighted pixel residuals as Eigen's Levenberg–Marquardt expects them: x = (rotation vector w
/// applied before R0 about the camera axes, translation t); R = exp(w)·R0. Central-difference Jacobian.
struct PoseResiduals {
  using Scalar = double;
  enum { InputsAtCompileTime = Eigen::Dynamic, ValuesAtCompileTime = Eigen::Dynamic };
  using InputType = Eigen::VectorXd;
  using ValueType = Eigen::VectorXd;
  using JacobianType = Eigen::MatrixXd;
  const CameraModel* cam;
  const std::vector<Correspondence>* c;
  Eigen::Matrix3d R0;
  int inputs() const { return 6; }
  int values() const { return static_cast<int>(2 * c->size()); }
  int operator()(const Eigen::VectorXd& x, Eigen::VectorXd& f) const {
    f = residuals(*cam, *c, exp_so3(x.head<3>()) * R0, x.tail<3>());
    if (!f.allFinite()) f.setConstant(1e6);  // behind the camera or off the lens: a large, finite cost
    return 0;
  }
  int df(const Eigen::VectorXd& x, Eigen::MatrixXd& jac) const {
    Eigen::VectorXd plus(values()), minus(values());
    for (int k = 0; k < 6; ++k) {
      const double h = k < 3 ? 1e-6 : 1e-4;
      Eigen::VectorXd d = Eigen::VectorXd::Zero(6);
      d[k] = h;
      (*this)(x + d, plus), (*this)(x - d, minus);
      jac.col(k) = (plus - minus) / (2 * h);
    }
    return 0;
  }
};

/// Levenberg–Marquardt (Eigen's) on the weighted reprojection error; keeps the start if it does not improve.
void refine(const CameraModel& cam, const std::vector<Correspondence>& c, Eigen::Matrix3d& R,
            Eigen::Vector3d& t, int max_iterations) {
  PoseResiduals f{&cam, &c, R};
  Eigen::VectorXd x(6), r0(f.values()), r1(f.values());
  x << 0, 0, 0, t;
  f(x, r0);
  Eigen::LevenbergMarquardt<PoseResiduals> lm(f);
  lm.parameters.maxfev = std::max(1, max_iterations) * 10;
  lm.parameters.xtol = 1e-14;
  lm.parameters.ftol = 1e-14;
  lm.minimize(x);
  if (!x.allFinite()) return;
  f(x, r1);
  if (!(r1.squaredNorm() < r0.squaredNorm())) return;
  R = exp_so3(x.head<3>()) * f.R0;
  t = x.tail<3>();
}

}  // namespace

const TagLayout::Tag* TagLayout::find(int id) const {
  for (const auto& t : tags)
    if (t.id == id) return &t;
  return nullptr;
}

TagLayout read_tag_layout(const std::filesystem::path& path) {
  const std::string file = path.string();
  if (!std::filesystem::is_regular_file(path)) throw InputError(file, "", "tag-layout file not found");
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::Exception& e) {
    throw InputError(file, "line " + std::to_string(e.mark.line + 1), "not a valid YAML/JSON file: " + e.msg);
  }
  if (!root.IsMap()) throw InputError(file, "", "expected a map with keys schema, family, tags");
  for (const auto& kv : root) {
    const std::string key = yaml_key(kv.first, file);
    if (key != "schema" && key != "family" && key != "tags")
      throw InputError(file, "key '" + key + "' (" + line_of(kv.first) + ")", "unknown key",
                       "known keys: schema family tags");
  }
  if (!root["schema"] || root["schema"].as<std::string>("") != "clearfit.tag-layout/1")
    throw InputError(file, "key 'schema'", "expected 'clearfit.tag-layout/1'");
  TagLayout layout;
  layout.path = path;
  if (root["family"]) layout.family = root["family"].as<std::string>("");
  if (!detail::create_family(layout.family))
    throw InputError(file, "key 'family' (" + line_of(root["family"]) + ")",
                     "unknown AprilTag family '" + layout.family + "'");
  const YAML::Node tags = root["tags"];
  if (!tags || !tags.IsSequence() || tags.size() == 0)
    throw InputError(file, "key 'tags'", "expected a list of tags with id and corners_mm");
  std::set<int> ids;
  for (const auto& n : tags) {
    const std::string where = "tag at " + line_of(n);
    if (!n.IsMap()) throw InputError(file, where, "expected {id, corners_mm, through_part}");
    for (const auto& kv : n) {
      const std::string key = yaml_key(kv.first, file);
      if (key != "id" && key != "corners_mm" && key != "through_part")
        throw InputError(file, where + ", key '" + key + "'", "unknown key",
                         "known keys: id corners_mm through_part");
    }
    TagLayout::Tag tag;
    try {
      tag.id = n["id"].as<int>();
      tag.through_part = n["through_part"] ? n["through_part"].as<bool>() : false;
      const YAML::Node c = n["corners_mm"];
      if (!c || !c.IsSequence() || c.size() != 4)
        throw InputError(file, where, "corners_mm must list 4 corners [x, y, z]");
      for (int k = 0; k < 4; ++k) {
        if (!c[k].IsSequence() || c[k].size() != 3)
          throw InputError(file, where, "corner " + std::to_string(k) + " must be [x, y, z] in mm");
        for (int a = 0; a < 3; ++a) tag.corners_mm[k][a] = c[k][a].as<double>();
      }
    } catch (const YAML::Exception& e) {
      throw InputError(
          file, where,
          "expected id (integer), corners_mm (4 x [x, y, z] numbers), through_part (true/false): " + e.msg);
    }
    if (!ids.insert(tag.id).second)
      throw InputError(file, where, "tag id " + std::to_string(tag.id) + " appears twice");
    const auto& p = tag.corners_mm;
    double lo = INFINITY, hi = 0;
    bool finite = true;
    for (int k = 0; k < 4; ++k) {
      finite &= p[k].allFinite();
      const double side = (p[(k + 1) % 4] - p[k]).norm();
      lo = std::min(lo, side), hi = std::max(hi, side);
    }
    const Eigen::Vector3d normal = (p[2] - p[0]).cross(p[3] - p[1]);
    const double off_plane = normal.norm() > 0 ? std::abs((p[1] - p[0]).dot(normal.normalized())) : INFINITY;
    const double diag_ratio = (p[2] - p[0]).norm() / std::max((p[3] - p[1]).norm(), 1e-300);
    if (!finite || !(lo > 0) || hi > 1.05 * lo || off_plane > 0.02 * lo || std::abs(diag_ratio - 1) > 0.05)
      throw InputError(
          file, where + " (id " + std::to_string(tag.id) + ")",
          "corners_mm are not the 4 corners of a square (sides " + significant_digits(lo, 4) + ".." +
              significant_digits(hi, 4) + " mm)",
          "list the outer corners of the black square in order bottom-left, bottom-right, top-right, "
          "top-left");
    layout.tags.push_back(tag);
  }
  return layout;
}

void PoseOptions::validate() const {
  if (max_iterations < 1 || max_iterations > 10000)
    throw std::invalid_argument("PoseOptions::max_iterations = " + std::to_string(max_iterations) +
                                ": must be 1..10000");
  if (!(outlier_sigma >= 0))
    throw std::invalid_argument("PoseOptions::outlier_sigma = " + significant_digits(outlier_sigma, 4) +
                                ": must be >= 0");
  if (!(min_outlier_px >= 0))
    throw std::invalid_argument("PoseOptions::min_outlier_px = " + significant_digits(min_outlier_px, 4) +
                                ": must be >= 0");
}

PartPose solve_part_pose(const CameraModel& camera, const TagLayout& layout,
                         const std::vector<std::vector<DetectedTag>>& detections,
                         const PoseOptions& options) {
  options.validate();
  PartPose pose;
  const std::string file = layout.path.string();
  std::vector<Correspondence> corr;
  std::set<int> refused, unknown, images;
  for (std::size_t i = 0; i < detections.size(); ++i)
    for (const auto& d : detections[i]) {
      const TagLayout::Tag* tag = layout.find(d.id);
      if (!tag) {
        unknown.insert(d.id);
        continue;
      }
      if (tag->through_part) {
        refused.insert(d.id);
        continue;
      }
      for (int k = 0; k < 4; ++k)
        if (d.weight[k] >= 0)
          corr.push_back({tag->corners_mm[k], d.corners[k], d.weight[k], d.id, static_cast<int>(i)});
    }
  for (int id : refused)
    pose.notes.push_back("tag " + std::to_string(id) +
                         " refused: flagged through_part (refraction would bias the pose)");
  if (!unknown.empty()) {
    std::string s;
    for (int id : unknown) {
      if (!s.empty()) s += ' ';
      s += std::to_string(id);
    }
    pose.notes.push_back("tags not in the layout ignored: " + s);
  }
  if (corr.size() < 4)
    throw InputError(file, "tags",
                     std::to_string(corr.size()) +
                         " usable corners of layout tags were seen; a pose needs at least 4 "
                         "(one tag), better several tags spread over the field of view",
                     "check the family and ids of the layout against the printed tags, and the images");

  // PnP seed on normalized undistorted coordinates.
  std::vector<Vec2> px(corr.size());
  for (std::size_t i = 0; i < corr.size(); ++i) px[i] = corr[i].pixel;
  const std::vector<Vec3> rays = camera.unproject(std::span<const Vec2>(px));
  std::vector<cv::Point3d> obj;
  std::vector<cv::Point2d> img;
  for (std::size_t i = 0; i < corr.size(); ++i)
    if (rays[i].allFinite() && rays[i].z() > 1e-6) {
      obj.emplace_back(corr[i].point_in_part.x(), corr[i].point_in_part.y(), corr[i].point_in_part.z());
      img.emplace_back(rays[i].x() / rays[i].z(), rays[i].y() / rays[i].z());
    }
  if (obj.size() < 4)
    throw InputError(file, "tags", "fewer than 4 corners can be unprojected through the camera model");
  cv::Mat rvec, tvec;
  if (!cv::solvePnP(obj, img, cv::Mat::eye(3, 3, CV_64F), cv::Mat(), rvec, tvec, false, cv::SOLVEPNP_SQPNP))
    throw InputError(file, "tags", "no pose fits the corners (PnP failed)",
                     "check the corner order of the layout");
  Eigen::Matrix3d R = rotation_from_rodrigues({rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2)});
  Eigen::Vector3d t(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));

  refine(camera, corr, R, t, options.max_iterations);
  if (options.outlier_sigma > 0) {
    const Eigen::VectorXd r = residuals(camera, corr, R, t);
    const double s = std::sqrt(r.squaredNorm() / std::max<double>(1, r.size() - 6));
    const double limit = std::max(options.outlier_sigma * s, options.min_outlier_px);
    std::vector<Correspondence> kept;
    for (std::size_t i = 0; i < corr.size(); ++i)
      if (r.segment<2>(2 * i).norm() <= limit) kept.push_back(corr[i]);
    if (kept.size() != corr.size() && kept.size() >= 4) {
      pose.outliers = static_cast<int>(corr.size() - kept.size());
      pose.notes.push_back(std::to_string(pose.outliers) + " corners dropped as outliers (residual > " +
                           significant_digits(limit, 4) + " px)");
      corr.swap(kept);
      refine(camera, corr, R, t, options.max_iterations);
    }
  }
  const Eigen::VectorXd r = residuals(camera, corr, R, t);
  if (!r.allFinite())
    throw InputError(file, "tags", "the solved pose puts corners behind the camera", "check the layout");
  const PoseResiduals at_pose{&camera, &corr, R};  // the Jacobian about the solution (w = 0)
  Eigen::VectorXd x0(6);
  x0 << 0, 0, 0, t;
  Eigen::MatrixXd J(at_pose.values(), 6);
  at_pose.df(x0, J);
  double wsum = 0;
  for (const auto& c : corr) wsum += c.weight * c.weight;
  pose.cam_from_part.rotation = R;
  pose.cam_from_part.translation = t;
  pose.corners = static_cast<int>(corr.size());
  pose.rms_px = std::sqrt(r.squaredNorm() / wsum);  // weighted RMS of the corners' 2D errors
  const double dof = std::max<double>(1, r.size() - 6);
  pose.noise_px = std::sqrt(r.squaredNorm() / dof);
  const Eigen::Matrix<double, 6, 6> info = J.transpose() * J;
  pose.covariance =
      pose.noise_px * pose.noise_px * info.ldlt().solve(Eigen::Matrix<double, 6, 6>::Identity());
  for (int a = 0; a < 3; ++a) {
    pose.sigma_rotation_deg[a] = std::sqrt(std::max(0.0, pose.covariance(a, a))) * 180 / M_PI;
    pose.sigma_translation_mm[a] = std::sqrt(std::max(0.0, pose.covariance(a + 3, a + 3)));
  }
  std::set<int> used;
  for (const auto& c : corr) used.insert(c.tag), images.insert(c.image);
  pose.tag_ids.assign(used.begin(), used.end());
  pose.tags = static_cast<int>(used.size());
  pose.images = static_cast<int>(images.size());
  if (pose.rms_px > 2)
    pose.notes.push_back("reprojection RMS " + significant_digits(pose.rms_px, 4) +
                         " px is large: check the layout (corner order, units, ids) and the camera model");
  if (pose.tags == 1)
    pose.notes.push_back(
        "only one tag seen: the pose rests on 4 close corners; spread several tags for a sturdy pose");
  return pose;
}

std::vector<int> tags_seen_through_part(const RayIndex& part, const PartPose& pose, const TagLayout& layout) {
  const Eigen::Vector3d centre = pose.cam_from_part.inverse().translation;  // camera centre, part frame
  std::vector<int> through;
  for (int id : pose.tag_ids) {
    const TagLayout::Tag* tag = layout.find(id);
    if (!tag) continue;
    bool hit = false;
    for (const auto& corner : tag->corners_mm) {
      const Eigen::Vector3d d = corner - centre;
      const double len = d.norm();
      if (!(len > 0.02)) continue;
      const RayHit h = part.intersect(Ray{centre, d / len, 0.0, len - 0.01});
      hit |= static_cast<bool>(h);
    }
    if (hit) through.push_back(id);
  }
  return through;
}

std::string part_pose_report_json(const PartPose& p) {
  const auto rt = p.cam_from_part.to_rt();
  nlohmann::json j = {
      {"schema", "clearfit.part-pose-report/1"},
      {"units", "mm"},
      {"cam_from_part", {{"r", {rt[0], rt[1], rt[2]}}, {"t", {rt[3], rt[4], rt[5]}}}},
      {"rms_px", p.rms_px},
      {"noise_px", p.noise_px},
      {"corners", p.corners},
      {"tags", p.tag_ids},
      {"images", p.images},
      {"outliers", p.outliers},
      {"sigma_translation_mm",
       {p.sigma_translation_mm.x(), p.sigma_translation_mm.y(), p.sigma_translation_mm.z()}},
      {"sigma_rotation_deg", {p.sigma_rotation_deg.x(), p.sigma_rotation_deg.y(), p.sigma_rotation_deg.z()}},
      {"notes", p.notes}};
  return j.dump(2) + "\n";
}

}  // namespace clearfit
