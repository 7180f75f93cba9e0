// Camera calibration: input checks, seeding (focal length from homographies,
// board poses by PnP on normalised points), mrcal's staged solve, the report's
// statistics, and projection uncertainty (mrcal's method).
#include "mrcal_api.hpp"
#include "mrcal_optimize_api.hpp"

#include <clearfit/camera/calibrate.hpp>
#include <clearfit/camera/projection_uncertainty.hpp>
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace clearfit {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

bool present(const Eigen::Vector3d& c) { return c.z() >= 0 && std::isfinite(c.x()) && std::isfinite(c.y()); }

// Fraction of row/column triples (three neighbouring corners) whose second
// difference exceeds half the local spacing: 0 for any lens and perspective
// view of the right grid, large when the grid's width or order is wrong.
double grid_inconsistency(const BoardObservation& v, const CalibrationGrid& g) {
  int triples = 0, bad = 0;
  auto at = [&](int i, int j) -> const Eigen::Vector3d& {
    return v.corners[static_cast<std::size_t>(i) * g.width + j];
  };
  auto check = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
    if (!present(a) || !present(b) || !present(c)) return;
    const Eigen::Vector2d qa = a.head<2>(), qb = b.head<2>(), qc = c.head<2>();
    const double spacing = 0.5 * (qc - qa).norm();
    ++triples;
    if (!(spacing > 0) || (qa + qc - 2 * qb).norm() > 0.5 * spacing) ++bad;
  };
  for (int i = 0; i < g.height; ++i)
    for (int j = 1; j + 1 < g.width; ++j) check(at(i, j - 1), at(i, j), at(i, j + 1));
  for (int i = 1; i + 1 < g.height; ++i)
    for (int j = 0; j < g.width; ++j) check(at(i - 1, j), at(i, j), at(i + 1, j));
  return triples ? double(bad) / triples : 0.0;
}

// Median distance (pixels) between neighbouring corners of a row or column; 0 without any.
double median_corner_spacing(const BoardObservation& v, const CalibrationGrid& g) {
  std::vector<double> d;
  for (int i = 0; i < g.height; ++i)
    for (int j = 0; j < g.width; ++j) {
      const Eigen::Vector3d& a = v.corners[static_cast<std::size_t>(i) * g.width + j];
      if (!present(a)) continue;
      if (j + 1 < g.width && present(v.corners[static_cast<std::size_t>(i) * g.width + j + 1]))
        d.push_back((v.corners[static_cast<std::size_t>(i) * g.width + j + 1] - a).head<2>().norm());
      if (i + 1 < g.height && present(v.corners[static_cast<std::size_t>(i + 1) * g.width + j]))
        d.push_back((v.corners[static_cast<std::size_t>(i + 1) * g.width + j] - a).head<2>().norm());
    }
  if (d.empty()) return 0;
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return d[d.size() / 2];
}

Eigen::Vector3d board_point(const CalibrationGrid& g, int i, int j) {
  return {j * g.spacing_mm, i * g.spacing_mm, 0};
}

// board_point with mrcal's board warp: the board sags along z by x2 * 4 u (1 - u) + y2 * 4 v (1 - v),
// u and v the column and row over the grid (0 to 1), i.e. x2 + y2 at the centre.
Eigen::Vector3d warped_board_point(const CalibrationGrid& g, int i, int j, const std::array<double, 2>& warp) {
  const double u = g.width > 1 ? double(j) / (g.width - 1) : 0.0, v = g.height > 1 ? double(i) / (g.height - 1) : 0.0;
  return board_point(g, i, j) + Eigen::Vector3d(0, 0, warp[0] * 4 * u * (1 - u) + warp[1] * 4 * v * (1 - v));
}

// Focal length (pixels) from the views' homographies with the principal point
// at the imager centre and square pixels (Zhang's orthogonality constraints
// solved for 1/f^2 in least squares); 0 when they do not determine it.
double focal_from_homographies(const std::vector<const BoardObservation*>& views, const CalibrationGrid& g,
                               int w, int h) {
  const double cx = 0.5 * (w - 1), cy = 0.5 * (h - 1);
  double suu = 0, suv = 0;
  for (const auto* v : views) {
    std::vector<cv::Point2d> src, dst;
    for (int i = 0; i < g.height; ++i)
      for (int j = 0; j < g.width; ++j) {
        const auto& c = v->corners[static_cast<std::size_t>(i) * g.width + j];
        if (!present(c)) continue;
        src.emplace_back(j * g.spacing_mm, i * g.spacing_mm);
        dst.emplace_back(c.x() - cx, c.y() - cy);
      }
    if (src.size() < 6) continue;
    const cv::Mat H = cv::findHomography(src, dst, 0);
    if (H.empty()) continue;
    const Eigen::Vector3d a(H.at<double>(0, 0), H.at<double>(1, 0), H.at<double>(2, 0));
    const Eigen::Vector3d b(H.at<double>(0, 1), H.at<double>(1, 1), H.at<double>(2, 1));
    // u / f^2 + v = 0 for both constraints, each normalised to unit scale.
    const std::array<std::pair<double, double>, 2> rows{
        std::pair{a.x() * b.x() + a.y() * b.y(), a.z() * b.z()},
        std::pair{a.x() * a.x() + a.y() * a.y() - b.x() * b.x() - b.y() * b.y(),
                  a.z() * a.z() - b.z() * b.z()}};
    const double norm = a.head<2>().squaredNorm() + b.head<2>().squaredNorm();
    for (auto [u, vv] : rows) {
      u /= norm;
      vv /= norm;
      suu += u * u;
      suv += u * vv;
    }
  }
  if (!(suu > 0)) return 0;
  const double inv_f2 = -suv / suu;
  if (!(inv_f2 > 0)) return 0;
  const double f = 1.0 / std::sqrt(inv_f2);
  return (f > 0.1 * w && f < 50.0 * w) ? f : 0;
}

bool is_splined(const std::string& lensmodel) {
  return lensmodel.rfind("LENSMODEL_SPLINED_STEREOGRAPHIC", 0) == 0;
}
bool is_opencv(const std::string& lensmodel) { return lensmodel.rfind("LENSMODEL_OPENCV", 0) == 0; }
int num_params(const std::string& lensmodel) { return detail::lens_or_throw(lensmodel).num_params; }

// The models solved in turn, the target last.
std::vector<std::string> lensmodel_chain(const std::string& target) {
  if (is_splined(target)) return {"LENSMODEL_STEREOGRAPHIC", target};
  if (target == "LENSMODEL_OPENCV12") return {"LENSMODEL_PINHOLE", "LENSMODEL_OPENCV8", target};
  if (is_opencv(target) || target == "LENSMODEL_CAHVOR") return {"LENSMODEL_PINHOLE", target};
  return {target};
}

// Intrinsics of `to` seeded from a solution of `from`: the core, plus the
// distortions that mean the same (OpenCV models extend each other), else zeros.
std::vector<double> extend_intrinsics(const std::vector<double>& from, const std::string& from_model,
                                      const std::string& to_model) {
  std::vector<double> to(static_cast<std::size_t>(num_params(to_model)), 0.0);
  std::copy_n(from.begin(), 4, to.begin());
  if (is_opencv(from_model) && is_opencv(to_model))
    std::copy_n(from.begin() + 4, std::min(from.size(), to.size()) - 4, to.begin() + 4);
  return to;
}

// cam_from_board by PnP on normalised coordinates (rays through `model`).
std::optional<std::array<double, 6>> pose_by_pnp(const BoardObservation& v, const CalibrationGrid& g,
                                                 const CameraModel& model) {
  std::vector<Vec2> pixels;
  std::vector<cv::Point3d> object;
  for (int i = 0; i < g.height; ++i)
    for (int j = 0; j < g.width; ++j) {
      const auto& c = v.corners[static_cast<std::size_t>(i) * g.width + j];
      if (!present(c)) continue;
      pixels.emplace_back(c.x(), c.y());
      object.emplace_back(j * g.spacing_mm, i * g.spacing_mm, 0.0);
    }
  const std::vector<Vec3> rays = model.unproject(pixels);
  std::vector<cv::Point2d> normalised;
  std::vector<cv::Point3d> obj;
  for (std::size_t k = 0; k < rays.size(); ++k)
    if (rays[k].allFinite() && rays[k].z() > 1e-3) {
      normalised.emplace_back(rays[k].x() / rays[k].z(), rays[k].y() / rays[k].z());
      obj.push_back(object[k]);
    }
  if (obj.size() < 4) return std::nullopt;
  cv::Mat rvec, tvec;
  const cv::Mat K = cv::Mat::eye(3, 3, CV_64F);
  if (!cv::solvePnP(obj, normalised, K, cv::Mat(), rvec, tvec, false, cv::SOLVEPNP_IPPE)) return std::nullopt;
  std::array<double, 6> rt{rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2),
                           tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)};
  if (!(rt[5] > 0)) return std::nullopt;
  for (double x : rt)
    if (!std::isfinite(x)) return std::nullopt;
  return rt;
}

std::string cell_name(int cx, int cy, int nx, int ny) {
  const std::string vert = cy == 0 ? "top" : cy == ny - 1 ? "bottom" : "middle";
  const std::string horz = cx == 0 ? "left" : cx == nx - 1 ? "right" : "centre";
  return vert + "-" + horz + " (cell " + std::to_string(cx) + "," + std::to_string(cy) + ")";
}

}  // namespace

void CalibrationGrid::validate() const {
  if (width < 2 || height < 2)
    throw InputError(
        "", "board grid",
        "needs at least 2 x 2 corners, got " + std::to_string(width) + " x " + std::to_string(height));
  if (!(std::isfinite(spacing_mm) && spacing_mm > 0))
    throw InputError("", "board spacing",
                     "must be a positive number of millimetres, got " + significant_digits(spacing_mm, 3));
}

void CalibrationOptions::validate() const {
  auto fail = [](const std::string& field, const std::string& value, const std::string& rule) {
    throw std::invalid_argument("CalibrationOptions::" + field + " = " + value + ": " + rule);
  };
  if (!detail::parse_lens(lensmodel)) fail("lensmodel", lensmodel, "must be a full mrcal lens model name");
  if (lensmodel.find("CAHVORE") != std::string::npos)
    fail("lensmodel", lensmodel, "CAHVORE is not supported");
  if (!(std::isfinite(focal_px) && focal_px >= 0))
    fail("focal_px", significant_digits(focal_px, 3), "must be >= 0 (0: estimate)");
  if (!(fallback_fov_deg > 1 && fallback_fov_deg < 179))
    fail("fallback_fov_deg", significant_digits(fallback_fov_deg, 3), "must be in (1, 179)");
  if (!(uncertainty_distance_mm >= 0))
    fail("uncertainty_distance_mm", significant_digits(uncertainty_distance_mm, 3), "must be >= 0");
  if (coverage_cells_x < 1 || coverage_cells_y < 1)
    fail("coverage_cells", std::to_string(coverage_cells_x), "must be >= 1");
  if (uncertainty_nodes_x < 2 || uncertainty_nodes_y < 2)
    fail("uncertainty_nodes", std::to_string(std::min(uncertainty_nodes_x, uncertainty_nodes_y)), "must be >= 2 (the image's edges)");
  if (min_views < 1) fail("min_views", std::to_string(min_views), "must be >= 1");
  if (!(max_grid_inconsistency > 0 && max_grid_inconsistency <= 1))
    fail("max_grid_inconsistency", significant_digits(max_grid_inconsistency, 3), "must be in (0, 1]");
}

void check_calibration_lensmodel(const std::string& lensmodel) {
  // CameraModel::validate names the lens model's problem; the rest of the
  // probe is valid by construction.
  const auto lens = detail::parse_lens(lensmodel);
  CameraModel probe{
      lensmodel, std::vector<double>(lens ? static_cast<std::size_t>(lens->num_params) : 4u, 1.0), 1, 1, {},
      {}};
  probe.validate();
}

double projection_difference_px(const CameraModel& a, const CameraModel& b, const Eigen::Vector2d& q) {
  const Vec3 ray = a.unproject(q);
  if (!ray.allFinite()) return std::numeric_limits<double>::quiet_NaN();
  return (b.project(ray) - q).norm();
}

namespace {

/// The views with enough corners (checked against the grid and each other); notes for the ones skipped.
struct UsableViews {
  std::vector<const BoardObservation*> used;
  std::vector<int> index;  ///< into the given views
};

UsableViews usable_views(const std::vector<BoardObservation>& views, const CalibrationGrid& grid, const CalibrationOptions& options,
                         CalibrationResult& res) {
  const std::size_t per_view = static_cast<std::size_t>(grid.width) * grid.height;
  if (views.empty())
    throw InputError("", "views", "no board views were given",
                     "pass images or a corners file with detections");
  std::vector<const BoardObservation*> used;
  std::vector<int> used_index;
  res.views.resize(views.size());
  const BoardObservation* first_sized = nullptr;
  for (std::size_t k = 0; k < views.size(); ++k) {
    const auto& v = views[k];
    res.views[k].image = v.image;
    if (v.corners.size() != per_view)
      throw InputError(v.image, "corners",
                       "has " + std::to_string(v.corners.size()) + " corners; the board grid " +
                           std::to_string(grid.width) + " x " + std::to_string(grid.height) + " needs " +
                           std::to_string(per_view),
                       "check the board description");
    if (v.width <= 0 || v.height <= 0)
      throw InputError(v.image, "image size", "is unknown or not positive", "give the imager size");
    if (!first_sized) first_sized = &v;
    if (v.width != first_sized->width || v.height != first_sized->height)
      throw InputError(v.image, "image size",
                       std::to_string(v.width) + " x " + std::to_string(v.height) + " differs from " +
                           first_sized->image + " (" + std::to_string(first_sized->width) + " x " +
                           std::to_string(first_sized->height) + ")",
                       "calibrate one camera at one resolution; remove or resize the odd images");
    if (v.width > CameraModel::kMaxImagerSide || v.height > CameraModel::kMaxImagerSide)
      throw InputError(v.image, "image size", std::to_string(v.width) + " x " + std::to_string(v.height) + " is larger than any imager");
    for (std::size_t c = 0; c < v.corners.size(); ++c) {
      const auto& p = v.corners[c];
      // A corner more than an imager away from the imager is no detection of it (a typo, a unit error).
      if (present(p) && (std::abs(p.x() - 0.5 * v.width) > 1.5 * v.width || std::abs(p.y() - 0.5 * v.height) > 1.5 * v.height))
        throw InputError(v.image, "corner " + std::to_string(c),
                         "at (" + std::to_string(p.x()) + ", " + std::to_string(p.y()) + ") px lies far outside the " +
                             std::to_string(v.width) + " x " + std::to_string(v.height) + " imager",
                         "check the corners file and the image size");
    }
    const int n = static_cast<int>(std::count_if(v.corners.begin(), v.corners.end(), present));
    if (n < 4) {
      res.notes.push_back(v.image + ": " +
                          (n == 0 ? "no corners detected" : "only " + std::to_string(n) + " corners") +
                          "; view skipped");
      continue;
    }
    const double bad = grid_inconsistency(v, grid);
    const double spacing = median_corner_spacing(v, grid);
    if (bad > options.max_grid_inconsistency && spacing < 4)
      throw InputError(v.image, "corners",
                       "are only " + significant_digits(spacing, 2) +
                           " px apart (the median between neighbours): the board is too small or too far away in "
                           "this view for its corners to be measured",
                       "bring the board closer (its corners at least 10 px apart) or leave this view out");
    if (bad > options.max_grid_inconsistency)
      throw InputError(
          v.image, "corners",
          "are inconsistent with a " + std::to_string(grid.width) + " x " + std::to_string(grid.height) +
              " grid: " + significant_digits(100 * bad, 2) +
              "% of neighbouring corner triples are not in a row (the board description disagrees "
              "with the printed board)",
          "check the board's rows, columns and corner order against the printed board");
    used.push_back(&v);
    used_index.push_back(static_cast<int>(k));
  }
  if (static_cast<int>(used.size()) < options.min_views)
    throw InputError("", "views",
                     "only " + std::to_string(used.size()) + " views have board corners; at least " +
                         std::to_string(options.min_views) + " are needed",
                     "take more images of the board: tilted, at several distances, covering the whole image");
  if (static_cast<int>(used.size()) < options.recommended_views)
    res.warnings.push_back("only " + std::to_string(used.size()) + " usable views; use " +
                           std::to_string(options.recommended_views) +
                           " or more (tilted boards at several distances, reaching the image corners)");
  return {used, used_index};
}

/// The focal length to start from: the seed model's, the option's, the board homographies', or a field of view.
double seed_focal(const std::vector<const BoardObservation*>& used, const CalibrationGrid& grid, const CalibrationOptions& options,
                  int W, int H, CalibrationResult& res) {
  double f = 0;
  if (options.seed) {
    if (options.seed->lensmodel != options.lensmodel || options.seed->width != W || options.seed->height != H)
      throw InputError(options.seed->path.string(), "lensmodel",
                       "the seed model must have the lens model " + options.lensmodel +
                           " and the imager size " + std::to_string(W) + " x " + std::to_string(H));
    f = options.seed->intrinsics[0];
    res.focal_seed_method = "seed model";
  } else if (options.focal_px > 0) {
    f = options.focal_px;
    res.focal_seed_method = "option";
  } else if ((f = focal_from_homographies(used, grid, W, H)) > 0) {
    res.focal_seed_method = "homographies";
  } else {
    f = 0.5 * W / std::tan(0.5 * options.fallback_fov_deg * std::numbers::pi / 180);
    res.focal_seed_method = "field of view";
    res.notes.push_back(
        "the board homographies did not determine the focal length (boards facing the camera?); "
        "started from a " +
        significant_digits(options.fallback_fov_deg, 3) + " degree field of view");
  }

  res.focal_seed_px = f;
  return f;
}

/// The mrcal problem with every view that PnP could pose; frame_view maps its frames to the given views.
struct PosedProblem {
  detail::BoardProblem problem;
  std::vector<int> frame_view;
  int given_missing = 0;  ///< corners missing in the input (not outliers)
};

PosedProblem posed_problem(const UsableViews& u, const CalibrationGrid& grid, const CalibrationOptions& options,
                           const std::vector<std::string>& chain, double f, int W, int H, CalibrationResult& res) {
  const std::vector<const BoardObservation*>& used = u.used;
  const std::vector<int>& used_index = u.index;
  detail::BoardProblem problem;
  problem.imager_width = W;
  problem.imager_height = H;
  problem.grid_width = grid.width;
  problem.grid_height = grid.height;
  problem.spacing_mm = grid.spacing_mm;
  const bool seed_full = options.seed.has_value();
  std::string current = seed_full ? options.lensmodel : chain.front();
  problem.lensmodel = current;
  if (seed_full)
    problem.intrinsics = options.seed->intrinsics;
  else {
    problem.intrinsics.assign(static_cast<std::size_t>(num_params(current)), 0.0);
    problem.intrinsics[0] = problem.intrinsics[1] = f;
    problem.intrinsics[2] = 0.5 * (W - 1);
    problem.intrinsics[3] = 0.5 * (H - 1);
  }
  CameraModel seed_model{current, problem.intrinsics, W, H, {}, {}};
  std::vector<int> frame_view;  // problem frame -> index into views
  for (std::size_t k = 0; k < used.size(); ++k) {
    const auto rt = pose_by_pnp(*used[k], grid, seed_model);
    if (!rt) {
      res.notes.push_back(used[k]->image + ": no board pose could be found (PnP failed); view skipped");
      continue;
    }
    problem.frames.push_back(*rt);
    problem.corners.insert(problem.corners.end(), used[k]->corners.begin(), used[k]->corners.end());
    frame_view.push_back(used_index[k]);
  }
  const int nf = static_cast<int>(problem.frames.size());
  if (nf < options.min_views)
    throw InputError("", "views", "only " + std::to_string(nf) + " views could be posed", "take more images");
  for (auto& c : problem.corners)
    if (!present(c)) c = {-1, -1, -1};
  const int given_missing = static_cast<int>(
      std::count_if(problem.corners.begin(), problem.corners.end(), [](auto& c) { return c.z() < 0; }));

  return {problem, frame_view, given_missing};
}

/// The corner noise mrcal's regularisation is sized for, pixels (see staged_solve), and the largest
/// weight scale used (corners of 0.01 px: sharper is noise-free synthetic data, not a camera).
constexpr double kRegularizationNoisePx = 1.0, kMaxCornerWeightScale = 100.0;

/// RMS per coordinate of the weighted residuals of the inlier corners, pixels; 0 without any.
double inlier_noise_px(const detail::BoardProblem& problem, const detail::SolveOutput& out) {
  double sum2 = 0;
  int n = 0;
  for (std::size_t c = 0; c < problem.corners.size(); ++c)
    if (problem.corners[c].z() > 0) {
      sum2 += out.board_residuals[2 * c] * out.board_residuals[2 * c] +
              out.board_residuals[2 * c + 1] * out.board_residuals[2 * c + 1];
      n += 2;
    }
  return n ? std::sqrt(sum2 / n) : 0.0;
}

/// How much better `b` fits the corners that are inliers of both solutions than `a` does, in units of
/// b's noise squared (the sum over those corners of |r_a|^2 - |r_b|^2, over b's inlier noise^2).
double misfit_gain(const detail::BoardProblem& a, const detail::SolveOutput& a_out, const detail::BoardProblem& b,
                   const detail::SolveOutput& b_out) {
  const double noise = inlier_noise_px(b, b_out);
  double gain = 0;
  for (std::size_t c = 0; c < a.corners.size(); ++c)
    if (a.corners[c].z() > 0 && b.corners[c].z() > 0)
      gain += Eigen::Vector2d(a_out.board_residuals[2 * c], a_out.board_residuals[2 * c + 1]).squaredNorm() -
              Eigen::Vector2d(b_out.board_residuals[2 * c], b_out.board_residuals[2 * c + 1]).squaredNorm();
  return noise > 0 ? gain / (noise * noise) : 0.0;
}

/// The staged solve: board poses, the core, then each lens model of the chain; outliers on the last;
/// then again with the regularisation scaled to the corners' noise.
struct FinalSolve {
  detail::Selection selection;
  detail::SolveOutput output;
};

FinalSolve staged_solve(detail::BoardProblem& problem, const std::vector<std::string>& chain, const CalibrationOptions& options,
                        CalibrationResult& res) {
  const auto progress = [&](const std::string& s) {
    if (options.progress) options.progress(s);
  };
  const bool seed_full = options.seed.has_value();
  auto solve = [&](const detail::Selection& s, const std::string& stage) {
    progress("solving: " + stage + " (" + problem.lensmodel + ")");
    detail::SolveOutput out = detail::optimize(problem, s);
    std::string said;
    for (const std::string& m : out.messages) said += (said.empty() ? "" : "; ") + m;
    if (!out.ok)
      throw InputError("", "calibration",
                       "mrcal's solver failed at the stage '" + stage + "' (" + problem.lensmodel + ")" +
                           (said.empty() ? "" : ": mrcal says: " + said),
                       "check the board description and the corners; give --focal with a better guess");
    if (!said.empty()) res.warnings.push_back("mrcal's solver, at the stage '" + stage + "': " + said);
    if (out.outlier_passes > 0)  // the count is the result's (missing corners are mrcal's outliers too)
      progress("outliers thrown out and solved again (" + std::to_string(out.outlier_passes) + (out.outlier_passes == 1 ? " pass)" : " passes)"));
    return out;
  };
  const std::vector<Eigen::Vector3d> given = problem.corners;  // before any outlier is marked
  detail::Selection final_sel;
  detail::SolveOutput final_out;
  res.seed_rms_px = solve({.frames = true}, "board poses").rms_px;
  if (!seed_full) solve({.core = true, .frames = true}, "intrinsics core and board poses");
  for (std::size_t k = seed_full ? chain.size() - 1 : 0; k < chain.size(); ++k) {
    if (chain[k] != problem.lensmodel) {
      problem.intrinsics = extend_intrinsics(problem.intrinsics, problem.lensmodel, chain[k]);
      problem.lensmodel = chain[k];
    }
    const bool has_distortions = num_params(problem.lensmodel) > 4, last = k + 1 == chain.size();
    if (!has_distortions && !last && !seed_full) continue;  // its core was solved above
    final_sel = {.core = true,
                 .distortions = has_distortions,
                 .frames = true,
                 .warp = options.solve_calobject_warp,
                 .regularization = options.regularization && has_distortions,
                 .outlier_rejection = false};
    // Outliers are looked for only on the last model (they stick), where
    // mrcal's own loop solves, rejects and solves again.
    final_sel.outlier_rejection = options.outlier_rejection && last;
    final_out = solve(
        final_sel, final_sel.outlier_rejection ? "all parameters with outlier rejection" : "all parameters");
  }
  if (!final_sel.regularization || !options.scale_regularization_to_noise) return {final_sel, final_out};
  // mrcal sizes its regularisation for corners of about 1 px noise, whatever
  // the residuals are: with sharper corners it outweighs the data, and where
  // the true distortions are far from zero (a wide lens) it biases the fit
  // where the views thin out (those corners are then thrown out as outliers)
  // and the model extrapolates badly. Solved again with the weights scaled by
  // 1 px / noise, the given corners back (outliers are looked for anew), from
  // this solution. Where the data show no bias mrcal's sizing is kept: its
  // pull towards zero then steadies the image corners no view reached.
  const double noise = inlier_noise_px(problem, final_out);
  const double scale = noise > 0 ? std::min(kRegularizationNoisePx / noise, kMaxCornerWeightScale) : 1.0;
  if (scale > 1.1) {
    const detail::BoardProblem sized = problem;
    const detail::SolveOutput sized_out = final_out;
    for (std::size_t c = 0; c < problem.corners.size(); ++c) problem.corners[c].z() = given[c].z();
    problem.weight_scale = scale;
    final_out = solve(final_sel, "all parameters, regularisation scaled to the corners' noise");
    // Kept only where mrcal's sizing biased the fit: relaxing it freed k distortion
    // parameters, which without a bias lowers the misfit by at most a chi-square of k degrees
    // of freedom (under 0.5 noise variances measured on sharp-enough views; 100-470 on the wide lens).
    const double gain = misfit_gain(sized, sized_out, problem, final_out);
    const double k = num_params(problem.lensmodel) - 4;
    if (gain > k + 4 * std::sqrt(2 * k)) {
      res.notes.push_back("mrcal's regularisation, sized for 1 px corners, biased the lens model: solved again with it "
                          "scaled to the corners' noise (weights x " + significant_digits(scale, 3) +
                          "), which fits the corners better by " + significant_digits(gain, 3) + " noise variances");
    } else {
      problem = sized;
      final_out = sized_out;
    }
  }
  res.corner_weight_scale = problem.weight_scale;
  return {final_sel, final_out};
}

/// Per-view poses, distances, tilts, residuals, coverage; the RMS, outliers and worst corners.
void collect_results(const std::vector<BoardObservation>& views, const CalibrationGrid& grid, const PosedProblem& pp,
                     const detail::SolveOutput& final_out, const CalibrationOptions& options, int W, int H, CalibrationResult& res) {
  const detail::BoardProblem& problem = pp.problem;
  const std::vector<int>& frame_view = pp.frame_view;
  const int nf = static_cast<int>(problem.frames.size());
  const std::size_t per_view = static_cast<std::size_t>(grid.width) * grid.height;
  res.model = CameraModel{problem.lensmodel, problem.intrinsics, W, H, {}, {}};
  res.mrcal_rms_px = final_out.rms_px;
  res.calobject_warp_x_mm = problem.warp[0];
  res.calobject_warp_y_mm = problem.warp[1];
  res.coverage_cells_x = options.coverage_cells_x;
  res.coverage_cells_y = options.coverage_cells_y;
  res.coverage.assign(static_cast<std::size_t>(res.coverage_cells_x) * res.coverage_cells_y, 0);
  std::vector<CornerResidual> inliers;
  for (int fi = 0; fi < nf; ++fi) {
    auto& view = res.views[static_cast<std::size_t>(frame_view[fi])];
    view.used = true;
    view.cam_from_board = Rigid3::from_rt(problem.frames[fi]);
    const Eigen::Vector3d centre =
        view.cam_from_board.apply(board_point(grid, grid.height - 1, grid.width - 1) * 0.5);
    view.distance_mm = centre.norm();
    view.tilt_deg =
        std::acos(std::min(1.0, std::abs(view.cam_from_board.rotation(2, 2)))) * 180 / std::numbers::pi;
    double sum2 = 0;
    for (int i = 0; i < grid.height; ++i)
      for (int j = 0; j < grid.width; ++j) {
        const std::size_t idx =
            static_cast<std::size_t>(fi) * per_view + static_cast<std::size_t>(i) * grid.width + j;
        const Eigen::Vector3d& c = problem.corners[idx];
        const Eigen::Vector3d& given =
            views[static_cast<std::size_t>(frame_view[fi])].corners[idx - fi * per_view];
        const double w = std::abs(given.z());
        const Eigen::Vector2d r(final_out.board_residuals[2 * idx], final_out.board_residuals[2 * idx + 1]);
        CornerResidual cr{frame_view[fi], i, j, w > 0 ? r.norm() / w : 0.0, given.head<2>()};
        if (c.z() < 0) {
          if (!present(given)) continue;
          // mrcal gives an outlier a zero residual: its distance from the solution's projection instead.
          cr.error_px = (res.model.project(view.cam_from_board.apply(warped_board_point(grid, i, j, problem.warp))) -
                         given.head<2>()).norm();
          res.outlier_corners.push_back(cr);
          continue;
        }
        sum2 += cr.error_px * cr.error_px;
        ++view.corners;
        inliers.push_back(cr);
        const int cx = std::clamp(static_cast<int>((c.x() + 0.5) / W * res.coverage_cells_x), 0,
                                  res.coverage_cells_x - 1);
        const int cy = std::clamp(static_cast<int>((c.y() + 0.5) / H * res.coverage_cells_y), 0,
                                  res.coverage_cells_y - 1);
        ++res.coverage[static_cast<std::size_t>(cy) * res.coverage_cells_x + cx];
      }
    view.rms_px = view.corners ? std::sqrt(sum2 / view.corners) : 0.0;
  }
  res.corners_used = static_cast<int>(inliers.size());
  double sum2 = 0;
  for (const auto& c : inliers) sum2 += c.error_px * c.error_px;
  res.rms_px = inliers.empty() ? 0.0 : std::sqrt(sum2 / (2.0 * inliers.size()));
  res.outliers = final_out.outliers - pp.given_missing;
  std::sort(inliers.begin(), inliers.end(), [](auto& a, auto& b) { return a.error_px > b.error_px; });
  res.worst_corners.assign(inliers.begin(),
                           inliers.begin() + std::min<std::ptrdiff_t>(10, std::ssize(inliers)));

}

/// Warnings on the views' spread, tilt, coverage, RMS and outliers; returns the median board distance.
double calibration_warnings(CalibrationResult& res) {
  std::vector<double> distances, tilts;
  for (const auto& v : res.views)
    if (v.used) {
      distances.push_back(v.distance_mm);
      tilts.push_back(v.tilt_deg);
    }
  std::vector<double> sorted = distances;
  std::sort(sorted.begin(), sorted.end());
  const double median_distance = sorted[sorted.size() / 2];
  if ((sorted.back() - sorted.front()) < 0.15 * median_distance)
    res.warnings.push_back(
        "all boards are at about one distance (" + significant_digits(sorted.front(), 4) + " to " +
        significant_digits(sorted.back(), 4) +
        " mm): the focal length and the distance are nearly interchangeable; add views nearer "
        "and farther away");
  if (*std::max_element(tilts.begin(), tilts.end()) < 15)
    res.warnings.push_back(
        "every board faces the camera (tilt below 15 degrees): the focal length is poorly "
        "determined; add views with the board tilted 30-45 degrees");
  std::vector<std::string> empty;
  for (int cy = 0; cy < res.coverage_cells_y; ++cy)
    for (int cx = 0; cx < res.coverage_cells_x; ++cx)
      if (res.coverage[static_cast<std::size_t>(cy) * res.coverage_cells_x + cx] == 0)
        empty.push_back(cell_name(cx, cy, res.coverage_cells_x, res.coverage_cells_y));
  if (!empty.empty()) {
    std::string list;
    for (std::size_t k = 0; k < empty.size() && k < 8; ++k) list += (k ? ", " : "") + empty[k];
    if (empty.size() > 8) list += ", ...";
    res.warnings.push_back(std::to_string(empty.size()) + " of " + std::to_string(res.coverage.size()) +
                           " regions of the image have no board corners (" + list +
                           "): the lens model is extrapolated there; add views that reach them");
  }
  if (res.rms_px > 1.0)
    res.warnings.push_back("RMS reprojection error " + significant_digits(res.rms_px, 3) +
                           " px is large: check focus, motion blur, the board's flatness and the lens model");
  if (res.outliers > 0.05 * (res.outliers + res.corners_used))
    res.warnings.push_back(std::to_string(res.outliers) + " corners were rejected as outliers (over 5%)");
  return median_distance;
}

/// Refuses a solve the views cannot determine: fewer than min_views distinct board poses (a view
/// given twice, or a still board filmed twice, adds nothing), or a focal length no lens has (under a
/// twentieth of the imager's larger side, a field of view far beyond 180 degrees), which is where the
/// optimiser drifts when every board faces the camera at one distance.
void check_determined(const CalibrationResult& res, const CalibrationOptions& options, int W, int H) {
  std::vector<const CalibrationResult::View*> distinct;
  std::string repeat;
  for (const auto& v : res.views) {
    if (!v.used) continue;
    const auto same = std::find_if(distinct.begin(), distinct.end(), [&](const CalibrationResult::View* d) {
      const Rigid3 rel = d->cam_from_board.inverse() * v.cam_from_board;
      return rodrigues_from_rotation(rel.rotation).norm() < 1e-3 && rel.translation.norm() < 1e-3 * v.distance_mm;
    });
    if (same == distinct.end()) distinct.push_back(&v);
    else if (repeat.empty()) repeat = " (" + v.image + " shows the board where " + (*same)->image + " does)";
  }
  if (static_cast<int>(distinct.size()) < options.min_views)
    throw InputError("", "views",
                     "show the board in only " + std::to_string(distinct.size()) + " distinct pose(s)" + repeat +
                         "; at least " + std::to_string(options.min_views) + " are needed",
                     "move the board (or the camera) between the images: tilted, at several distances, covering the whole image");
  const double f = std::min(res.model.intrinsics[0], res.model.intrinsics[1]);
  if (!(f >= std::max(W, H) / 20.0)) {
    std::string why;
    for (const std::string& w : res.warnings)
      if (w.find("one distance") != std::string::npos || w.find("faces the camera") != std::string::npos) why += "; " + w;
    throw InputError("", "views",
                     "do not determine the focal length: the solve gave " + significant_digits(f, 3) + " px for a " +
                         std::to_string(W) + " x " + std::to_string(H) + " imager (a field of view beyond 180 degrees)" + why,
                     "add views with the board tilted 30-45 degrees, at several distances, reaching the image corners");
  }
}

/// The projection uncertainty (mrcal's method): the state covariance through dq/db at the nodes of a grid
/// spanning the imager, and at its centre.
void projection_uncertainty(const detail::BoardProblem& problem, detail::Selection usel, const CalibrationOptions& options,
                            double median_distance, int W, int H, CalibrationResult& res) {
  const auto progress = [&](const std::string& s) {
    if (options.progress) options.progress(s);
  };
  const int nf = static_cast<int>(problem.frames.size());
  const auto tu = Clock::now();
  progress("projection uncertainty");
  usel.outlier_rejection = false;
  const detail::PackedJacobian pj = detail::packed_jacobian(problem, usel);
  const int ns = static_cast<int>(pj.scale.size());
  const int nb = pj.n_board_measurements;
  // sigma: the spread of the inlier residual coordinates (mrcal's Python
  // takes the std of all board residuals, missing corners' zeros included,
  // which underestimates it when corners are missing).
  double sx = 0, sxx = 0;
  int nx = 0;
  for (std::size_t c = 0; c < problem.corners.size(); ++c)
    if (problem.corners[c].z() >= 0)
      for (int e = 0; e < 2; ++e) {
        const double v = pj.board_residuals[2 * c + e];
        sx += v;
        sxx += v * v;
        ++nx;
      }
  res.observed_pixel_sigma_px = nx ? std::sqrt(std::max(0.0, sxx / nx - (sx / nx) * (sx / nx))) : 0.0;
  const Eigen::MatrixXd A = pj.J.transpose() * pj.J;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(A);
  const Eigen::MatrixXd Ainv_JobsT = ldlt.solve(pj.J.topRows(nb).transpose());  // Nstate x nb
  const Eigen::MatrixXd covariance = Ainv_JobsT * Ainv_JobsT.transpose();       // packed, / sigma^2

  res.uncertainty_nodes_x = options.uncertainty_nodes_x;
  res.uncertainty_nodes_y = options.uncertainty_nodes_y;
  res.uncertainty_distance_mm =
      options.uncertainty_distance_mm > 0 ? options.uncertainty_distance_mm : median_distance;
  std::vector<Vec2> q = uncertainty_sample_pixels(ProjectionUncertainty::Layout::nodes, res.uncertainty_nodes_x,
                                                   res.uncertainty_nodes_y, W, H);
  q.emplace_back(0.5 * (W - 1), 0.5 * (H - 1));
  const std::size_t nq = q.size();
  std::vector<Vec3> p_cam = res.model.unproject(q);
  for (auto& p : p_cam) p = p.normalized() * res.uncertainty_distance_mm;
  // mrcal's mean-frames reference: the point is carried into every board
  // frame and back through that frame's (noisy) pose, then averaged.
  std::vector<Rigid3> poses(static_cast<std::size_t>(nf));
  for (int fi = 0; fi < nf; ++fi) poses[fi] = Rigid3::from_rt(problem.frames[fi]);
  // dq/db_packed by central differences, one state element at a time.
  std::vector<Eigen::MatrixXd> dq_db(nq, Eigen::MatrixXd::Zero(2, ns));
  constexpr double h = 1e-6;
  const int n_intr = static_cast<int>(problem.intrinsics.size());
  CameraModel perturbed = res.model;
  std::vector<Vec3> pts(nq);
  auto column = [&](int k, const std::vector<Vec2>& qp, const std::vector<Vec2>& qm) {
    for (std::size_t n = 0; n < nq; ++n) dq_db[n].col(k) = (qp[n] - qm[n]) / (2 * h);
  };
  if (pj.istate_intrinsics >= 0)
    for (int k = 0; k < n_intr; ++k) {
      const double step = h * pj.scale[pj.istate_intrinsics + k];
      perturbed.intrinsics[k] = res.model.intrinsics[k] + step;
      const auto qp = perturbed.project(p_cam);
      perturbed.intrinsics[k] = res.model.intrinsics[k] - step;
      const auto qm = perturbed.project(p_cam);
      perturbed.intrinsics[k] = res.model.intrinsics[k];
      column(pj.istate_intrinsics + k, qp, qm);
    }
  for (int fi = 0; fi < nf; ++fi) {
    const Rigid3 board_from_cam = poses[fi].inverse();
    for (int e = 0; e < 6; ++e) {
      const int k = pj.istate_frames + 6 * fi + e;
      std::vector<Vec2> qpm[2];
      for (int sgn = 0; sgn < 2; ++sgn) {
        auto rt = problem.frames[fi];
        rt[e] += (sgn ? -1 : 1) * h * pj.scale[k];
        const Rigid3 moved = Rigid3::from_rt(rt);
        for (std::size_t n = 0; n < nq; ++n)
          pts[n] = p_cam[n] + (moved.apply(board_from_cam.apply(p_cam[n])) - p_cam[n]) / nf;
        qpm[sgn] = res.model.project(pts);
      }
      column(k, qpm[0], qpm[1]);
    }
  }
  const double sigma = res.observed_pixel_sigma_px;
  res.uncertainty_px.resize(nq - 1);
  for (std::size_t n = 0; n < nq; ++n) {
    const Eigen::Matrix2d var = dq_db[n] * covariance * dq_db[n].transpose() * sigma * sigma;
    const double worst =
        std::sqrt(std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(var).eigenvalues()(1)));
    if (n + 1 < nq)
      res.uncertainty_px[n] = std::isfinite(worst) ? worst : -1;
    else
      res.uncertainty_center_px = std::isfinite(worst) ? worst : -1;
  }
  res.uncertainty_seconds = seconds_since(tu);
}

}  // namespace

CalibrationResult calibrate_camera(const std::vector<BoardObservation>& views, const CalibrationGrid& grid,
                                   const CalibrationOptions& options) {
  const auto t0 = Clock::now();
  check_calibration_lensmodel(options.lensmodel);
  options.validate();
  grid.validate();
  CalibrationResult res;
  const UsableViews u = usable_views(views, grid, options, res);
  const int W = u.used.front()->width, H = u.used.front()->height;
  const std::vector<std::string> chain = lensmodel_chain(options.lensmodel);
  for (std::size_t k = 0; k < chain.size(); ++k) res.lensmodel_chain += (k ? " -> " : "") + chain[k];
  const double f = seed_focal(u.used, grid, options, W, H, res);
  PosedProblem pp = posed_problem(u, grid, options, chain, f, W, H, res);
  const FinalSolve fs = staged_solve(pp.problem, chain, options, res);
  res.solve_seconds = seconds_since(t0);
  collect_results(views, grid, pp, fs.output, options, W, H, res);
  const double median_distance = calibration_warnings(res);
  check_determined(res, options, W, H);
  if (options.compute_uncertainty) projection_uncertainty(pp.problem, fs.selection, options, median_distance, W, H, res);
  return res;
}

}  // namespace clearfit
