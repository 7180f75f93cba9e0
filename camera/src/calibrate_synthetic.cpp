// Synthetic calibration data (true corners through a known lens, plus noise)
// and projection-difference grids: the ground truth of tests and benchmarks.
#include <clearfit/camera/calibrate.hpp>

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <stdexcept>

namespace clearfit {

std::vector<double> projection_difference_grid(const CameraModel& a, const CameraModel& b, int nx, int ny,
                                               const std::vector<int>& fit_weights, const std::vector<Vec2>& also_at) {
  if (nx < 1 || ny < 1) throw std::invalid_argument("projection_difference_grid: nx, ny must be >= 1");
  if (!fit_weights.empty() && fit_weights.size() != static_cast<std::size_t>(nx) * ny)
    throw std::invalid_argument("projection_difference_grid: fit_weights must have nx * ny entries");
  std::vector<Vec2> q;
  for (int cy = 0; cy < ny; ++cy)
    for (int cx = 0; cx < nx; ++cx)
      q.emplace_back((cx + 0.5) * a.width / nx - 0.5, (cy + 0.5) * a.height / ny - 0.5);
  q.insert(q.end(), also_at.begin(), also_at.end());
  std::vector<Vec3> rays = a.unproject(q);
  if (!fit_weights.empty()) {
    const std::vector<Vec3> rays_b = b.unproject(q);
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (std::size_t k = 0; k < fit_weights.size(); ++k)
      if (fit_weights[k] > 0 && rays[k].allFinite() && rays_b[k].allFinite())
        cov += double(fit_weights[k]) * rays_b[k].normalized() * rays[k].normalized().transpose();
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d fix = Eigen::Matrix3d::Identity();
    fix(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1 : 1;
    const Eigen::Matrix3d R = svd.matrixU() * fix * svd.matrixV().transpose();  // b_from_a
    for (auto& r : rays) r = R * r;
  }
  const std::vector<Vec2> qb = b.project(rays);
  std::vector<double> out(q.size());
  for (std::size_t k = 0; k < q.size(); ++k) out[k] = (qb[k] - q[k]).norm();
  return out;
}

std::vector<BoardObservation> synthesize_views(const CameraModel& truth, const CalibrationGrid& grid,
                                               const SyntheticViewsOptions& o,
                                               std::vector<Rigid3>* cam_from_board) {
  grid.validate();
  truth.validate();
  if (o.views < 1 || !(o.noise_px >= 0) ||
      !(o.min_distance_mm > 0 && o.max_distance_mm >= o.min_distance_mm) ||
      !(o.min_tilt_deg >= 0 && o.max_tilt_deg >= o.min_tilt_deg && o.max_tilt_deg < 90))
    throw std::invalid_argument("synthesize_views: invalid SyntheticViewsOptions");
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> u01(0, 1);
  std::normal_distribution<double> noise(0, o.noise_px);
  const double deg = std::numbers::pi / 180;
  const Eigen::Vector3d centre_in_board(0.5 * (grid.width - 1) * grid.spacing_mm,
                                        0.5 * (grid.height - 1) * grid.spacing_mm, 0);
  std::vector<BoardObservation> out;
  if (cam_from_board) cam_from_board->clear();
  const std::size_t n = static_cast<std::size_t>(grid.width) * grid.height;
  for (int attempts = 0; static_cast<int>(out.size()) < o.views; ++attempts) {
    if (attempts > 1000 * o.views)
      throw std::invalid_argument("synthesize_views: the board does not fit the imager");
    // Board centre on the ray of a random pixel, at a random distance.
    const Vec2 q(u01(rng) * (truth.width - 1), u01(rng) * (truth.height - 1));
    const Vec3 ray = truth.unproject(q);
    if (!ray.allFinite()) continue;
    const double distance = o.min_distance_mm + u01(rng) * (o.max_distance_mm - o.min_distance_mm);
    // Facing the camera (board z along the optical axis), spun about its
    // normal, then tilted about a random in-plane axis.
    const double tilt = (o.min_tilt_deg + u01(rng) * (o.max_tilt_deg - o.min_tilt_deg)) * deg;
    const double axis_angle = u01(rng) * 2 * std::numbers::pi, spin = (u01(rng) - 0.5) * 60 * deg;
    const Eigen::Matrix3d R =
        (Eigen::AngleAxisd(tilt, Eigen::Vector3d(std::cos(axis_angle), std::sin(axis_angle), 0)) *
         Eigen::AngleAxisd(spin, Eigen::Vector3d::UnitZ()))
            .toRotationMatrix();
    Rigid3 pose;
    pose.rotation = R;
    pose.translation = ray.normalized() * distance - R * centre_in_board;
    BoardObservation v;
    v.width = truth.width;
    v.height = truth.height;
    std::vector<Vec3> pts(n);
    for (int i = 0; i < grid.height; ++i)
      for (int j = 0; j < grid.width; ++j)
        pts[static_cast<std::size_t>(i) * grid.width + j] =
            pose.apply(Eigen::Vector3d(j * grid.spacing_mm, i * grid.spacing_mm, 0));
    const std::vector<Vec2> px = truth.project(pts);
    int inside = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const Vec2 p = px[k] + Vec2(noise(rng), noise(rng));
      const bool in = px[k].allFinite() && p.x() > -0.5 && p.y() > -0.5 && p.x() < truth.width - 0.5 &&
                      p.y() < truth.height - 0.5;
      v.corners.emplace_back(in ? Eigen::Vector3d(p.x(), p.y(), 1.0) : Eigen::Vector3d(-1, -1, -1));
      inside += in;
    }
    if (inside < o.min_inside_fraction * static_cast<double>(n)) continue;
    char name[32];
    std::snprintf(name, sizeof name, "frame%03d.png", static_cast<int>(out.size()));
    v.image = name;
    v.tags_used = 0;
    out.push_back(std::move(v));
    if (cam_from_board) cam_from_board->push_back(pose);
  }
  return out;
}

}  // namespace clearfit
