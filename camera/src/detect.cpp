// AprilTag board detection, straight-edge corner refinement (in pixels or
// through the lens model), folders of images, mrcal's corners.vnl.
#include <clearfit/atomic_file.hpp>
#include <clearfit/camera/detect.hpp>
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>

#include "apriltag_family_internal.hpp"

#include <apriltag/apriltag.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>

namespace clearfit {

namespace {

using V2 = Eigen::Vector2d;

cv::Mat to_gray(const cv::Mat& image) {
  if (image.empty()) throw std::invalid_argument("detect: empty image");
  if (image.depth() != CV_8U)
    throw std::invalid_argument("detect: expected an 8-bit image, got depth " +
                                std::to_string(image.depth()));
  cv::Mat gray;
  if (image.channels() == 1)
    gray = image;
  else if (image.channels() == 3)
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  else if (image.channels() == 4)
    cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  else
    throw std::invalid_argument("detect: expected 1, 3 or 4 channels, got " +
                                std::to_string(image.channels()));
  return gray.isContinuous() ? gray : gray.clone();
}

/// Bilinear sample of a CV_32F image at mrcal pixel (x, y); NaN outside the pixel centres.
double sample(const cv::Mat& f, double x, double y) {
  if (!(x >= 0 && y >= 0 && x <= f.cols - 1 && y <= f.rows - 1)) return std::nan("");
  const int i = std::min(static_cast<int>(x), f.cols - 2), j = std::min(static_cast<int>(y), f.rows - 2);
  const double fx = x - i, fy = y - j;
  const float* r0 = f.ptr<float>(j);
  const float* r1 = f.ptr<float>(j + 1);
  return (1 - fy) * ((1 - fx) * r0[i] + fx * r0[i + 1]) + fy * ((1 - fx) * r1[i] + fx * r1[i + 1]);
}

/// Pixels <-> the plane where tag edges are straight: the pixels themselves
/// without a lens, normalized undistorted coordinates (x/z, y/z) with one.
struct Plane {
  const CameraModel* lens = nullptr;
  std::vector<V2> to_u(const std::vector<V2>& px) const {
    if (!lens) return px;
    std::vector<Vec3> rays = lens->unproject(std::span<const Vec2>(px));
    std::vector<V2> u(px.size());
    for (std::size_t i = 0; i < px.size(); ++i)
      u[i] = rays[i].z() > 1e-9 ? V2(rays[i].x() / rays[i].z(), rays[i].y() / rays[i].z()) : V2(NAN, NAN);
    return u;
  }
  std::vector<V2> to_px(const std::vector<V2>& u) const {
    if (!lens) return u;
    std::vector<Vec3> p(u.size());
    for (std::size_t i = 0; i < u.size(); ++i) p[i] = {u[i].x(), u[i].y(), 1.0};
    return lens->project(std::span<const Vec3>(p));
  }
};

/// A line n.x = d (n unit) with its fit statistics in pixels.
struct Line {
  V2 n = V2::Zero();
  double d = 0;
  double sigma_px = 0;  // RMS residual of the edge points, px
  int count = 0;
  V2 centroid = V2::Zero();
  double half_length = 0;  // half the spread of the points along the line (u units)
  double scale = 1;        // px per u unit, mean
};

/// Weighted total least squares line through points (weights w), one pass of
/// 3-sigma outlier rejection. `scale[i]` converts residuals to pixels.
std::optional<Line> fit_line(std::vector<V2> pts, std::vector<double> scale) {
  for (int pass = 0; pass < 2; ++pass) {
    if (pts.size() < 5) return std::nullopt;
    double wsum = 0;
    V2 c = V2::Zero();
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const double w = scale[i] * scale[i];
      c += w * pts[i];
      wsum += w;
    }
    c /= wsum;
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (std::size_t i = 0; i < pts.size(); ++i)
      cov += scale[i] * scale[i] * (pts[i] - c) * (pts[i] - c).transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov);
    Line l;
    l.n = es.eigenvectors().col(0);
    l.d = l.n.dot(c);
    l.centroid = c;
    double ss = 0, smean = 0, tmin = 1e300, tmax = -1e300;
    const V2 dir(-l.n.y(), l.n.x());
    std::vector<double> r(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) {
      r[i] = (l.n.dot(pts[i]) - l.d) * scale[i];
      ss += r[i] * r[i];
      smean += scale[i];
      const double t = dir.dot(pts[i] - c);
      tmin = std::min(tmin, t), tmax = std::max(tmax, t);
    }
    l.count = static_cast<int>(pts.size());
    l.sigma_px = std::sqrt(ss / std::max<std::size_t>(1, pts.size() - 2));
    l.half_length = 0.5 * (tmax - tmin);
    l.scale = smean / pts.size();
    if (pass == 1) return l;
    const double limit = std::max(3 * l.sigma_px, 0.02);
    std::vector<V2> keep;
    std::vector<double> keep_scale;
    for (std::size_t i = 0; i < pts.size(); ++i)
      if (std::abs(r[i]) <= limit) keep.push_back(pts[i]), keep_scale.push_back(scale[i]);
    if (keep.size() == pts.size()) return l;
    pts.swap(keep);
    scale.swap(keep_scale);
  }
  return std::nullopt;
}

/// 1-sigma offset of a fitted line at point q (px): the centre offset plus the
/// lever arm of the direction error (points spread uniformly over the line).
double line_sigma_at(const Line& l, const V2& q) {
  const V2 dir(-l.n.y(), l.n.x());
  const double rho = l.half_length > 0 ? dir.dot(q - l.centroid) / l.half_length : 1.0;
  return l.sigma_px * std::sqrt((1 + 3 * rho * rho) / l.count);
}

struct TagFit {
  bool ok = false;
  std::array<V2, 4> corners;         // px
  std::array<double, 4> sigma_px{};  // per corner
  std::string why;
  double cell_px = 0;    // narrowest bit cell, px
  double blur_px = 0;    // median edge width as a Gaussian sigma, px
  double saturated = 0;  // fraction of edge profiles with an end at 0 or 255
};

/// Refines one tag's four corners (px, AprilTag order) by straight-line fits
/// to its black-square edges in the plane of `plane`.
TagFit fit_tag(const cv::Mat& f, const std::array<V2, 4>& start, int cells_at_border, const Plane& plane,
               const RefineOptions& opt) {
  TagFit fit;
  fit.corners = start;
  for (int iter = 0; iter < opt.iterations; ++iter) {
    std::vector<double> widths;
    int profiles = 0, saturated = 0;
    const std::vector<V2> u = plane.to_u({fit.corners.begin(), fit.corners.end()});
    for (const V2& q : u)
      if (!q.allFinite()) return fit.why = "a corner cannot be unprojected", fit;
    std::array<Line, 4> lines;
    for (int e = 0; e < 4; ++e) {
      const V2 a = u[e], b = u[(e + 1) % 4];
      const double len_px = (fit.corners[(e + 1) % 4] - fit.corners[e]).norm();
      // Stay inside the black border strip (one cell): the narrowest cell of the quad.
      double cell_px = len_px;
      for (int k = 0; k < 4; ++k)
        cell_px = std::min(cell_px, (fit.corners[(k + 1) % 4] - fit.corners[k]).norm());
      cell_px /= cells_at_border;
      fit.cell_px = cell_px;
      const double h = std::min(opt.max_window_px, 0.45 * cell_px);
      if (h < 0.8) return fit.why = "tag too small (bit cell " + significant_digits(cell_px, 3) + " px)", fit;
      const int n = std::clamp(static_cast<int>(len_px * (1 - 2 * opt.edge_margin)), 6, 200);
      const V2 nu = V2(-(b - a).y(), (b - a).x()).normalized();
      const double delta = 1e-3 * (b - a).norm();
      std::vector<V2> su;
      su.reserve(2 * n);
      for (int i = 0; i < n; ++i) {
        const double s = opt.edge_margin + (1 - 2 * opt.edge_margin) * (i + 0.5) / n;
        su.push_back(a + s * (b - a));
        su.push_back(a + s * (b - a) + delta * nu);
      }
      const std::vector<V2> sp = plane.to_px(su);
      std::vector<V2> edge_px;
      std::vector<double> scale;
      const int steps = static_cast<int>(std::ceil(h / 0.1));
      std::vector<double> prof(2 * steps + 1);
      for (int i = 0; i < n; ++i) {
        const V2 p = sp[2 * i], dq = sp[2 * i + 1] - p;
        if (!p.allFinite() || !dq.allFinite() || dq.norm() <= 0) continue;
        const V2 np = dq.normalized();
        bool inside = true;
        for (int k = -steps; k <= steps; ++k) {
          const V2 q = p + (h * k / steps) * np;
          prof[k + steps] = sample(f, q.x(), q.y());
          if (std::isnan(prof[k + steps])) {
            inside = false;
            break;
          }
        }
        if (!inside) continue;
        // Edge position from the area under the normalised profile: for a step
        // blurred by any symmetric kernel, integral of (I - lo) / (hi - lo) over
        // [-h, h] equals h - s (interpolation ripples integrate to ~0).
        const int end = std::max(1, steps / 4);
        double lo = 0, hi = 0;
        for (int k = 0; k < end; ++k) lo += prof[k], hi += prof[2 * steps - k];
        lo /= end, hi /= end;
        if (std::abs(hi - lo) < opt.min_contrast) continue;
        ++profiles;
        saturated += std::min(lo, hi) <= 1 || std::max(lo, hi) >= 254;
        double slope = 0;
        for (int k = 0; k < 2 * steps; ++k)
          slope = std::max(slope, std::abs(prof[k + 1] - prof[k]) * steps / h);
        widths.push_back(std::abs(hi - lo) / (slope * std::sqrt(2 * M_PI)));
        double area = 0;
        for (int k = 0; k < 2 * steps; ++k) area += 0.5 * (prof[k] + prof[k + 1]) - lo;
        const double best = h - area * (h / steps) / (hi - lo);
        if (!(std::abs(best) < h)) continue;
        edge_px.push_back(p + best * np);
        scale.push_back(dq.norm() / delta);
      }
      std::vector<V2> edge_u = plane.to_u(edge_px);
      std::vector<V2> pts;
      std::vector<double> sc;
      for (std::size_t i = 0; i < edge_u.size(); ++i)
        if (edge_u[i].allFinite()) pts.push_back(edge_u[i]), sc.push_back(scale[i]);
      const auto line = fit_line(std::move(pts), std::move(sc));
      if (!line) return fit.why = "edge " + std::to_string(e) + " has too few sharp points", fit;
      lines[e] = *line;
    }
    std::vector<V2> cu(4);
    for (int k = 0; k < 4; ++k) {
      const Line &l1 = lines[(k + 3) % 4], &l2 = lines[k];  // edges (k-1, k) and (k, k+1)
      Eigen::Matrix2d A;
      A << l1.n.transpose(), l2.n.transpose();
      const double det = A.determinant();
      if (std::abs(det) < 1e-3) return fit.why = "degenerate quad", fit;
      cu[k] = A.inverse() * V2(l1.d, l2.d);
      fit.sigma_px[k] = std::hypot(line_sigma_at(l1, cu[k]), line_sigma_at(l2, cu[k])) / std::abs(det);
    }
    if (!widths.empty()) {
      std::nth_element(widths.begin(), widths.begin() + widths.size() / 2, widths.end());
      fit.blur_px = widths[widths.size() / 2];
    }
    fit.saturated = profiles ? double(saturated) / profiles : 0;
    const std::vector<V2> cp = plane.to_px(cu);
    for (int k = 0; k < 4; ++k) {
      if (!cp[k].allFinite()) return fit.why = "a refined corner cannot be projected", fit;
      const double moved = (cp[k] - start[k]).norm();
      const double allowed = std::max(2.0, 0.5 * (start[(k + 1) % 4] - start[k]).norm() / cells_at_border);
      if (moved > allowed)
        return fit.why = "refinement moved a corner " + significant_digits(moved, 3) + " px", fit;
      fit.corners[k] = cp[k];
    }
  }
  fit.ok = true;
  return fit;
}

double weight_of(double sigma_px) { return std::clamp(0.1 / std::max(sigma_px, 1e-12), 0.05, 1.0); }

/// Corners of blurred or saturated edges are biased (the dark border strip is
/// only one cell wide; clipping moves the half-level point): a weight cap.
double quality_cap(const TagFit& fit) {
  double cap = 1.0;
  if (fit.blur_px > 0.2 * fit.cell_px) cap = std::min(cap, 0.2 * fit.cell_px / fit.blur_px);
  if (fit.saturated > 0.2) cap = std::min(cap, 0.3);
  return std::max(cap, 0.05);
}

/// Image-level notes about blur and saturation from the tags' fits.
void quality_notes(const std::vector<TagFit>& fits, std::vector<std::string>& notes) {
  if (fits.empty()) return;
  int blurred = 0, saturated = 0;
  double worst = 0;
  for (const auto& f : fits) {
    if (f.blur_px > 0.2 * f.cell_px) ++blurred, worst = std::max(worst, f.blur_px / f.cell_px);
    saturated += f.saturated > 0.2;
  }
  if (blurred)
    notes.push_back(
        "blurred: " + std::to_string(blurred) + " of " + std::to_string(fits.size()) +
        " tags have edges wider than 0.2 bit cells (up to " + significant_digits(worst, 2) +
        "); their corners may be biased and got lower weights (focus, shorter exposure, or closer)");
  if (saturated)
    notes.push_back(
        "overexposed: " + std::to_string(saturated) + " of " + std::to_string(fits.size()) +
        " tags have edges clipped at 0 or 255, which shifts the corners; their weights were lowered "
        "(reduce exposure or gain)");
}

struct Detector {
  detail::FamilyPtr family;
  apriltag_detector_t* td = nullptr;
  Detector(const std::string& name, int bits, const DetectOptions& o) : family(detail::create_family(name)) {
    if (!family) throw std::invalid_argument("detect: unknown family " + name);
    td = apriltag_detector_create();
    apriltag_detector_add_family_bits(td, family.get(), bits);
    td->quad_decimate = o.quad_decimate;
    td->quad_sigma = o.quad_sigma;
    td->refine_edges = true;
    td->decode_sharpening = o.decode_sharpening;
    td->nthreads = 1;
  }
  Detector(const Detector&) = delete;
  Detector& operator=(const Detector&) = delete;
  ~Detector() { apriltag_detector_destroy(td); }

  struct Tag {
    int id, hamming;
    double margin;
    std::array<V2, 4> p;  // mrcal convention
  };
  std::vector<Tag> detect(const cv::Mat& gray) const {
    image_u8_t im{gray.cols, gray.rows, static_cast<int32_t>(gray.step[0]),
                  const_cast<uint8_t*>(gray.ptr<uint8_t>())};
    zarray_t* dets = apriltag_detector_detect(td, &im);
    std::vector<Tag> tags;
    for (int i = 0; i < zarray_size(dets); ++i) {
      apriltag_detection_t* det = nullptr;
      zarray_get(dets, i, &det);
      Tag t{det->id, det->hamming, det->decision_margin, {}};
      for (int k = 0; k < 4; ++k) t.p[k] = V2(det->p[k][0] - 0.5, det->p[k][1] - 0.5);
      tags.push_back(t);
    }
    apriltag_detections_destroy(dets);
    return tags;
  }
};

std::string id_list(const std::vector<int>& ids) {
  std::string s;
  for (std::size_t i = 0; i < ids.size() && i < 12; ++i) {
    if (i) s += ' ';
    s += std::to_string(ids[i]);
  }
  if (ids.size() > 12) s += " ...";
  return s;
}

/// Why a detected tag cannot be used (empty: usable). `count` = copies of its id.
std::string rejection(const Detector::Tag& t, int count, int width, int height, const DetectOptions& opt) {
  if (count > 1) return "seen " + std::to_string(count) + " times: all copies rejected";
  if (t.hamming > opt.max_hamming) return "rejected: " + std::to_string(t.hamming) + " bit errors";
  if (t.margin < opt.min_decision_margin)
    return "rejected as ambiguous: decision margin " + significant_digits(t.margin, 3) + " < " +
           significant_digits(opt.min_decision_margin, 3);
  for (const V2& p : t.p)
    if (!(p.x() >= opt.border_margin_px - 0.5 && p.y() >= opt.border_margin_px - 0.5 &&
          p.x() <= width - 0.5 - opt.border_margin_px && p.y() <= height - 0.5 - opt.border_margin_px))
      return "rejected: at the image border (partly outside)";
  const V2 d1 = t.p[2] - t.p[0], d2 = t.p[3] - t.p[1];
  if (std::abs(d1.x() * d2.y() - d1.y() * d2.x()) / 2 < 16) return "rejected: degenerate quad";
  return {};
}

/// Refined corners and weights of one accepted tag (AprilTag's corners at
/// weight 0.2 when the edge fit fails, with a note).
void refine_tag(const cv::Mat& f, const Detector::Tag& t, int cells_at_border, const Plane& plane,
                bool subpixel, std::array<V2, 4>& corners, std::array<double, 4>& weight,
                std::vector<TagFit>& fits, std::vector<std::string>& notes) {
  corners = t.p;
  weight.fill(1.0);
  if (!subpixel) return;
  const TagFit fit = fit_tag(f, t.p, cells_at_border, plane, RefineOptions{});
  if (fit.ok) {
    corners = fit.corners;
    fits.push_back(fit);
    for (int k = 0; k < 4; ++k)
      weight[k] = fit.sigma_px[k] > 1.0 ? -1.0 : std::min(weight_of(fit.sigma_px[k]), quality_cap(fit));
  } else {
    notes.push_back("tag " + std::to_string(t.id) + ": sub-pixel refinement failed (" + fit.why +
                    "), AprilTag corners kept at weight 0.2");
    weight.fill(0.2);
  }
}

BoardObservation detect_with(const Detector& detector, const cv::Mat& image, const Board& board,
                             const DetectOptions& opt, const std::string& name) {
  const cv::Mat gray = to_gray(image);
  BoardObservation obs;
  obs.image = name;
  obs.width = gray.cols;
  obs.height = gray.rows;
  obs.corners.assign(static_cast<std::size_t>(board.num_points()), Eigen::Vector3d(-1, -1, -1));
  const std::vector<Detector::Tag> tags = detector.detect(gray);

  std::map<int, int> count;
  for (const auto& t : tags) ++count[t.id];
  std::vector<int> foreign;
  cv::Mat f;
  if (opt.subpixel) gray.convertTo(f, CV_32F);
  std::vector<TagFit> fits;
  for (const auto& t : tags) {
    if (!board.has_tag(t.id)) {
      foreign.push_back(t.id);
      continue;
    }
    if (const std::string why = rejection(t, count[t.id], obs.width, obs.height, opt); !why.empty()) {
      obs.notes.push_back("tag " + std::to_string(t.id) + " " + why);
      continue;
    }
    std::array<V2, 4> corners;
    std::array<double, 4> weight;
    refine_tag(f, t, board.cells_at_border, Plane{}, opt.subpixel, corners, weight, fits, obs.notes);
    for (int k = 0; k < 4; ++k) {
      if (weight[k] < 0) continue;
      const GridIndex g = *board.corner_grid_index(t.id, k);
      obs.corners[static_cast<std::size_t>(board.point_index(g))] = {corners[k].x(), corners[k].y(),
                                                                     weight[k]};
    }
    ++obs.tags_used;
  }
  quality_notes(fits, obs.notes);
  std::sort(foreign.begin(), foreign.end());
  if (!foreign.empty())
    obs.notes.push_back(std::to_string(foreign.size()) + " " + board.layout.family +
                        " tags not on this board (ids " + id_list(foreign) + "; the board has " +
                        std::to_string(board.layout.first_id) + ".." +
                        std::to_string(board.layout.first_id + board.num_tags() - 1) + "): ignored");
  if (obs.tags_used == 0) {
    obs.notes.push_back("no " + board.layout.family + " board tag found");
    if (opt.probe_other_families) {
      for (const std::string fam : {"tag36h11", "tag36h10", "tag25h9", "tagStandard41h12", "tagCircle21h7"}) {
        if (fam == board.layout.family) continue;
        const Detector probe(fam, 0, opt);
        std::vector<int> ids;
        for (const auto& t : probe.detect(gray))
          if (t.margin >= opt.min_decision_margin) ids.push_back(t.id);
        if (ids.size() >= 2)
          obs.notes.push_back("found " + std::to_string(ids.size()) + " tags of family " + fam + " (ids " +
                              id_list(ids) + "): the board file says " + board.layout.family +
                              "; use the board file of the printed board");
      }
    }
  }
  return obs;
}

cv::Mat read_gray(const std::filesystem::path& path) {
  cv::Mat img = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
  if (img.empty())
    throw InputError(path.string(), "",
                     std::filesystem::exists(path) ? "cannot be read as an image" : "image not found",
                     "give PNG, JPEG, TIFF, BMP or PGM files");
  return img;
}

}  // namespace

int BoardObservation::num_valid() const {
  return static_cast<int>(
      std::count_if(corners.begin(), corners.end(), [](const Eigen::Vector3d& c) { return c.z() >= 0; }));
}

void DetectOptions::validate() const {
  auto fail = [](const char* field, double v, const char* rule) {
    throw std::invalid_argument(std::string("DetectOptions::") + field + " = " + significant_digits(v, 3) +
                                ": " + rule);
  };
  if (!(quad_decimate >= 1 && quad_decimate <= 8)) fail("quad_decimate", quad_decimate, "must be in 1..8");
  if (!(quad_sigma >= 0 && quad_sigma <= 10)) fail("quad_sigma", quad_sigma, "must be in 0..10");
  if (!(decode_sharpening >= 0 && decode_sharpening <= 4))
    fail("decode_sharpening", decode_sharpening, "must be in 0..4");
  if (max_hamming < 0 || max_hamming > 2) fail("max_hamming", max_hamming, "must be 0, 1 or 2");
  if (!(min_decision_margin >= 0)) fail("min_decision_margin", min_decision_margin, "must be >= 0");
  if (!(border_margin_px >= 0)) fail("border_margin_px", border_margin_px, "must be >= 0");
}

void RefineOptions::validate() const {
  auto fail = [](const char* field, double v, const char* rule) {
    throw std::invalid_argument(std::string("RefineOptions::") + field + " = " + significant_digits(v, 3) +
                                ": " + rule);
  };
  if (!(edge_margin >= 0 && edge_margin < 0.45)) fail("edge_margin", edge_margin, "must be in [0, 0.45)");
  if (!(max_window_px >= 0.8 && max_window_px <= 20))
    fail("max_window_px", max_window_px, "must be in 0.8..20");
  if (iterations < 1 || iterations > 20) fail("iterations", iterations, "must be 1..20");
  if (!(min_contrast >= 0)) fail("min_contrast", min_contrast, "must be >= 0");
}

BoardObservation detect_board(const cv::Mat& image, const Board& board, const DetectOptions& options,
                              const std::string& name) {
  options.validate();
  if (board.num_tags() == 0) throw std::invalid_argument("detect_board: empty board");
  const Detector detector(board.layout.family, options.max_hamming, options);
  return detect_with(detector, image, board, options, name);
}

std::vector<DetectedTag> detect_tags(const cv::Mat& image, const std::string& family,
                                     const DetectOptions& options, const CameraModel* lens,
                                     std::vector<std::string>* notes) {
  options.validate();
  if (!detail::create_family(family))
    throw InputError("", "family", "unknown AprilTag family '" + family + "'");
  const cv::Mat gray = to_gray(image);
  if (lens && (lens->width != gray.cols || lens->height != gray.rows))
    throw std::invalid_argument("detect_tags: the lens model's imager size differs from the image");
  const Detector detector(family, options.max_hamming, options);
  const auto fam = detail::create_family(family);
  const std::vector<Detector::Tag> tags = detector.detect(gray);
  std::map<int, int> count;
  for (const auto& t : tags) ++count[t.id];
  const bool refine = options.subpixel && detail::family_has_classic_border(*fam);
  cv::Mat f;
  if (refine) gray.convertTo(f, CV_32F);
  std::vector<std::string> own;
  std::vector<std::string>& out_notes = notes ? *notes : own;
  std::vector<TagFit> fits;
  std::vector<DetectedTag> out;
  for (const auto& t : tags) {
    if (const std::string why = rejection(t, count[t.id], gray.cols, gray.rows, options); !why.empty()) {
      out_notes.push_back("tag " + std::to_string(t.id) + " " + why);
      continue;
    }
    DetectedTag d;
    d.id = t.id;
    d.decision_margin = t.margin;
    refine_tag(f, t, fam->width_at_border, Plane{lens}, refine, d.corners, d.weight, fits, out_notes);
    out.push_back(d);
  }
  quality_notes(fits, out_notes);
  std::sort(out.begin(), out.end(), [](const DetectedTag& a, const DetectedTag& b) { return a.id < b.id; });
  return out;
}

BoardObservation detect_board_file(const std::filesystem::path& image, const Board& board,
                                   const DetectOptions& options) {
  return detect_board(read_gray(image), board, options, image.string());
}

std::vector<std::filesystem::path> list_images(const std::vector<std::filesystem::path>& inputs) {
  static const std::set<std::string> exts{".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm"};
  std::vector<std::filesystem::path> out;
  for (const auto& in : inputs) {
    if (std::filesystem::is_directory(in)) {
      std::vector<std::filesystem::path> found;
      for (const auto& e : std::filesystem::directory_iterator(in)) {
        std::string ext = e.path().extension().string();
        std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
        if (e.is_regular_file() && exts.count(ext)) found.push_back(e.path());
      }
      if (found.empty())
        throw InputError(in.string(), "", "folder has no images", "expected .png .jpg .tif .bmp .pgm files");
      std::sort(found.begin(), found.end());
      out.insert(out.end(), found.begin(), found.end());
    } else if (std::filesystem::is_regular_file(in)) {
      out.push_back(in);
    } else {
      throw InputError(in.string(), "", "no such file or folder");
    }
  }
  return out;
}

std::vector<BoardObservation> detect_boards(const std::vector<std::filesystem::path>& images,
                                            const Board& board, const DetectOptions& options,
                                            const std::function<void(int, int)>& progress) {
  options.validate();
  if (board.num_tags() == 0) throw std::invalid_argument("detect_boards: empty board");
  std::vector<BoardObservation> out(images.size());
  std::vector<std::optional<InputError>> errors(images.size());
  tbb::enumerable_thread_specific<std::unique_ptr<Detector>> detectors;
  std::mutex mutex;
  int done = 0;
  tbb::parallel_for(std::size_t{0}, images.size(), [&](std::size_t i) {
    auto& det = detectors.local();
    if (!det) det = std::make_unique<Detector>(board.layout.family, options.max_hamming, options);
    try {
      out[i] = detect_with(*det, read_gray(images[i]), board, options, images[i].string());
    } catch (const InputError& e) {
      errors[i] = e;
    }
    if (progress) {
      std::lock_guard lock(mutex);
      progress(++done, static_cast<int>(images.size()));
    }
  });
  for (std::size_t i = 0; i < images.size(); ++i)
    if (const auto& e = errors[i])  // the image as given names the file
      throw InputError(images[i].string(), e->element(), e->problem(), e->hint());
  return out;
}

std::string corners_vnl(const std::vector<BoardObservation>& observations, const Board& board) {
  std::ostringstream s;
  s.precision(9);
  s << "# filename x y weight\n";
  for (const auto& o : observations) {
    if (o.image.empty() || o.image.find_first_of(" \t\n\r") != std::string::npos)
      throw std::invalid_argument("corners_vnl: image name '" + o.image + "' is empty or has whitespace");
    if (o.corners.size() != static_cast<std::size_t>(board.num_points()))
      throw std::invalid_argument("corners_vnl: observation of " + o.image + " has " +
                                  std::to_string(o.corners.size()) + " corners, the board " +
                                  std::to_string(board.num_points()));
    if (!o.detected()) {
      s << o.image << " - - -\n";
      continue;
    }
    for (const auto& c : o.corners) {
      if (c.z() < 0)
        s << o.image << " - - -\n";
      else
        s << o.image << ' ' << c.x() << ' ' << c.y() << ' ' << c.z() << '\n';
    }
  }
  return s.str();
}

void write_corners_vnl(const std::vector<BoardObservation>& observations, const Board& board,
                       const std::filesystem::path& path) {
  write_file_atomically(path, corners_vnl(observations, board));
}

BoardObservation refine_corners(const cv::Mat& image, const BoardObservation& observation, const Board& board,
                                const CameraModel* lens, const RefineOptions& options) {
  options.validate();
  const cv::Mat gray = to_gray(image);
  if (gray.cols != observation.width || gray.rows != observation.height)
    throw std::invalid_argument("refine_corners: image is " + std::to_string(gray.cols) + "x" +
                                std::to_string(gray.rows) + ", the observation " +
                                std::to_string(observation.width) + "x" + std::to_string(observation.height));
  if (observation.corners.size() != static_cast<std::size_t>(board.num_points()))
    throw std::invalid_argument("refine_corners: observation does not match the board's grid");
  if (lens && (lens->width != gray.cols || lens->height != gray.rows))
    throw std::invalid_argument("refine_corners: the lens model's imager size differs from the image");
  cv::Mat f;
  gray.convertTo(f, CV_32F);
  BoardObservation out = observation;
  const Plane plane{lens};
  std::vector<TagFit> fits;
  for (int id = board.layout.first_id; id < board.layout.first_id + board.num_tags(); ++id) {
    std::array<V2, 4> start;
    std::array<int, 4> index{};
    bool complete = true;
    for (int k = 0; k < 4; ++k) {
      index[k] = board.point_index(*board.corner_grid_index(id, k));
      const Eigen::Vector3d& c = observation.corners[static_cast<std::size_t>(index[k])];
      complete &= c.z() >= 0;
      start[k] = c.head<2>();
    }
    if (!complete) continue;
    const TagFit fit = fit_tag(f, start, board.cells_at_border, plane, options);
    if (!fit.ok) {
      out.notes.push_back("tag " + std::to_string(id) + ": lens-aware refinement failed (" + fit.why +
                          "), corners kept");
      continue;
    }
    fits.push_back(fit);
    for (int k = 0; k < 4; ++k)
      out.corners[static_cast<std::size_t>(index[k])] =
          fit.sigma_px[k] > 1.0 ? Eigen::Vector3d(-1, -1, -1)
                                : Eigen::Vector3d(fit.corners[k].x(), fit.corners[k].y(),
                                                  std::min(weight_of(fit.sigma_px[k]), quality_cap(fit)));
  }
  std::vector<std::string> quality;
  quality_notes(fits, quality);
  for (auto& q : quality)
    if (std::find(out.notes.begin(), out.notes.end(), q) == out.notes.end()) out.notes.push_back(q);
  return out;
}

}  // namespace clearfit
