#include <clearfit/atomic_file.hpp>
#include <clearfit/camera/pose.hpp>
#include <clearfit/camera/pose_file.hpp>
#include <clearfit/error.hpp>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <sstream>

namespace clearfit {

Eigen::Matrix3d rotation_from_rodrigues(const Eigen::Vector3d& r) {
  const double theta2 = r.squaredNorm();
  Eigen::Matrix3d K;
  K << 0, -r.z(), r.y(),  //
      r.z(), 0, -r.x(),   //
      -r.y(), r.x(), 0;
  // R = I + a K + b K^2, a = sin(theta)/theta, b = (1 - cos(theta))/theta^2.
  double a, b;
  if (theta2 < 1e-8) {  // series; the next terms are below 1e-17
    a = 1.0 - theta2 / 6.0 + theta2 * theta2 / 120.0;
    b = 0.5 - theta2 / 24.0 + theta2 * theta2 / 720.0;
  } else {
    const double theta = std::sqrt(theta2);
    a = std::sin(theta) / theta;
    b = (1.0 - std::cos(theta)) / theta2;
  }
  return Eigen::Matrix3d::Identity() + a * K + b * K * K;
}

Eigen::Vector3d rodrigues_from_rotation(const Eigen::Matrix3d& rotation) {
  Eigen::Quaterniond q(rotation);
  q.normalize();
  if (q.w() < 0) q.coeffs() = -q.coeffs();  // angle in [0, pi]
  const Eigen::Vector3d v = q.vec();
  const double s = v.norm();
  if (s == 0.0) return Eigen::Vector3d::Zero();
  return (2.0 * std::atan2(s, q.w()) / s) * v;  // atan2 keeps full precision for tiny s
}

Rigid3 Rigid3::from_rt(const std::array<double, 6>& rt) {
  Rigid3 out;
  out.rotation = rotation_from_rodrigues({rt[0], rt[1], rt[2]});
  out.translation = {rt[3], rt[4], rt[5]};
  return out;
}

std::array<double, 6> Rigid3::to_rt() const {
  const Eigen::Vector3d r = rodrigues_from_rotation(rotation);
  return {r.x(), r.y(), r.z(), translation.x(), translation.y(), translation.z()};
}

Rigid3 Rigid3::inverse() const {
  Rigid3 out;
  out.rotation = rotation.transpose();
  out.translation = -(out.rotation * translation);
  return out;
}

Rigid3 operator*(const Rigid3& a_from_b, const Rigid3& b_from_c) {
  Rigid3 out;
  out.rotation = a_from_b.rotation * b_from_c.rotation;
  out.translation = a_from_b.rotation * b_from_c.translation + a_from_b.translation;
  return out;
}

namespace {

constexpr const char* kPoseSchema = "clearfit.pose/1";

std::string line_and_column(const std::string& text, std::size_t byte) {
  std::size_t line = 1, column = 1;
  for (std::size_t i = 0; i < byte && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
  }
  return "line " + std::to_string(line) + ", column " + std::to_string(column);
}

Eigen::Vector3d read_vector3(const nlohmann::json& parent, const char* key, const std::string& file,
                             const std::string& where) {
  const std::string element = "key '" + where + "." + key + "'";
  if (!parent.contains(key)) throw InputError(file, element, "is missing", "give 3 numbers");
  const auto& a = parent.at(key);
  if (!a.is_array() || a.size() != 3)
    throw InputError(file, element, "must be an array of 3 numbers, found " + a.dump());
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) {
    if (!a[i].is_number() || !std::isfinite(a[i].get<double>()))
      throw InputError(file, element, "must hold 3 finite numbers, found " + a.dump());
    v[i] = a[i].get<double>();
  }
  return v;
}

/// The optional uncertainty keys: "covariance" (6×6) or else "sigma" (independent 1-σ).
std::optional<PoseCovariance> read_pose_covariance(const nlohmann::json& j, const std::string& file) {
  if (j.contains("covariance")) {
    const auto& c = j["covariance"];
    const std::string element = "key 'covariance'";
    if (!c.is_array() || c.size() != 6)
      throw InputError(file, element, "must be 6 rows of 6 numbers (rotation about the camera axes in rad, then translation in mm)");
    PoseCovariance m;
    for (int r = 0; r < 6; ++r) {
      if (!c[r].is_array() || c[r].size() != 6) throw InputError(file, element + " row " + std::to_string(r + 1), "must hold 6 numbers");
      for (int k = 0; k < 6; ++k) {
        if (!c[r][k].is_number() || !std::isfinite(c[r][k].get<double>()))
          throw InputError(file, element + " row " + std::to_string(r + 1), "must hold 6 finite numbers, found " + c[r].dump());
        m(r, k) = c[r][k].get<double>();
      }
    }
    if ((m - m.transpose()).cwiseAbs().maxCoeff() > 1e-9 * std::max(1e-30, m.cwiseAbs().maxCoeff()) || (m.diagonal().array() < 0).any())
      throw InputError(file, element, "is not a covariance (symmetric, with a non-negative diagonal)",
                       "write the pose with `clearfit pose --out`, or drop the key");
    return m;
  }
  if (!j.contains("sigma")) return std::nullopt;
  const auto& s = j["sigma"];
  if (!s.is_object()) throw InputError(file, "key 'sigma'", "must be an object {\"rotation_deg\": [3], \"translation_mm\": [3]}");
  const Eigen::Vector3d r = read_vector3(s, "rotation_deg", file, "sigma"), t = read_vector3(s, "translation_mm", file, "sigma");
  if ((r.array() < 0).any() || (t.array() < 0).any())
    throw InputError(file, "key 'sigma'", "must hold 1-sigma values of 0 or more");
  PoseCovariance m = PoseCovariance::Zero();
  for (int a = 0; a < 3; ++a) m(a, a) = std::pow(r[a] * M_PI / 180, 2), m(a + 3, a + 3) = t[a] * t[a];
  return m;
}

}  // namespace

Rigid3 read_pose_json(const std::filesystem::path& path) { return read_pose_file(path).cam_from_part; }

PoseFile read_pose_file(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(file, "", "cannot open the pose file", "check the path");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();

  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(file, line_and_column(text, e.byte > 0 ? e.byte - 1 : 0),
                     std::string("is not valid JSON: ") + e.what());
  } catch (const nlohmann::json::exception& e) {  // a number beyond double's range (1e309)
    throw InputError(file, "", std::string("is not valid JSON: ") + e.what(), "numbers must be finite doubles");
  }
  if (!j.is_object()) throw InputError(file, "top level", "must be a JSON object");
  if (!j.contains("schema") || !j["schema"].is_string() || j["schema"].get<std::string>() != kPoseSchema)
    throw InputError(file, "key 'schema'", std::string("must be \"") + kPoseSchema + "\"",
                     "this file is not a clearfit pose file or is of another version");
  if (!j.contains("units") || j["units"] != "mm")
    throw InputError(file, "key 'units'", "must be \"mm\"", "pose translations are in millimetres");
  if (!j.contains("cam_from_part") || !j["cam_from_part"].is_object())
    throw InputError(file, "key 'cam_from_part'", "must be an object {\"r\": [3], \"t\": [3]}");
  const auto& p = j["cam_from_part"];
  const Eigen::Vector3d r = read_vector3(p, "r", file, "cam_from_part");
  const Eigen::Vector3d t = read_vector3(p, "t", file, "cam_from_part");
  return {Rigid3::from_rt({r.x(), r.y(), r.z(), t.x(), t.y(), t.z()}), read_pose_covariance(j, file)};
}

namespace {

void write_pose(const Rigid3& cam_from_part, const std::filesystem::path& path, const std::optional<PoseCovariance>& covariance) {
  const auto rt = cam_from_part.to_rt();
  for (double x : rt)
    if (!std::isfinite(x)) throw std::invalid_argument("write_pose_json: the pose is not finite");
  nlohmann::ordered_json j;
  j["schema"] = kPoseSchema;
  j["cam_from_part"] = {{"r", {rt[0], rt[1], rt[2]}}, {"t", {rt[3], rt[4], rt[5]}}};
  j["units"] = "mm";
  if (covariance) {
    if (!covariance->allFinite()) throw std::invalid_argument("write_pose_json: the covariance is not finite");
    const auto sd = [&](int a) { return std::sqrt(std::max(0.0, (*covariance)(a, a))); };
    j["sigma"] = {{"rotation_deg", {sd(0) * 180 / M_PI, sd(1) * 180 / M_PI, sd(2) * 180 / M_PI}},
                  {"translation_mm", {sd(3), sd(4), sd(5)}}};
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < 6; ++r) {
      nlohmann::json row = nlohmann::json::array();
      for (int k = 0; k < 6; ++k) row.push_back(0.5 * ((*covariance)(r, k) + (*covariance)(k, r)));
      rows.push_back(row);
    }
    j["covariance"] = rows;
  }
  write_file_atomically(path, j.dump(2) + "\n");
}

}  // namespace

void write_pose_json(const Rigid3& cam_from_part, const std::filesystem::path& path) {
  write_pose(cam_from_part, path, std::optional<PoseCovariance>());
}

void write_pose_json(const Rigid3& cam_from_part, const std::filesystem::path& path, const PoseCovariance& covariance) {
  write_pose(cam_from_part, path, std::optional<PoseCovariance>(covariance));
}


}  // namespace clearfit
