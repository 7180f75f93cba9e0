// Projection and unprojection through mrcal, batched and parallel (TBB), and
// the per-pixel ray grid of an imager.
#include "mrcal_api.hpp"

#include <clearfit/camera/pixel_unprojector.hpp>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>

namespace clearfit {
namespace {

using detail::Lens;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr std::size_t kProjectGrain = 2048;
constexpr std::size_t kUnprojectGrain = 256;

const double* checked_intrinsics(const CameraModel& model, const Lens& lens) {
  if (static_cast<int>(model.intrinsics.size()) != lens.num_params)
    throw std::invalid_argument("clearfit camera: " + model.lensmodel + " needs " + std::to_string(lens.num_params) +
                                " intrinsics, the model has " + std::to_string(model.intrinsics.size()));
  return model.intrinsics.data();
}

// q = project(p) for n points; dq_dp (2 per point) may be null. False if mrcal refused.
// Debian's mrcal 2.2 has two batch bugs (found by this module's tests): with
// N > 1, mrcal_project writes every point's dq_dp into the first two slots, and
// mrcal_project_pinhole writes every q into q[0]. So the special-case project
// functions are not used, and gradients are asked for one point at a time.
bool project_raw(const Lens& lens, const double* intrinsics, const mrcal_point3_t* p, int n, mrcal_point2_t* q,
                 mrcal_point3_t* dq_dp) {
  if (!dq_dp) return mrcal_project(q, nullptr, nullptr, p, n, &lens.model, intrinsics);
  for (int i = 0; i < n; ++i)
    if (!mrcal_project(q + i, dq_dp + 2 * i, nullptr, p + i, 1, &lens.model, intrinsics)) return false;
  return true;
}

// v = unproject(q) for n pixels (any length). False if mrcal refused.
bool unproject_raw(const Lens& lens, const double* intrinsics, const mrcal_point2_t* q, int n, mrcal_point3_t* v) {
  switch (lens.special) {
    case Lens::Special::pinhole: mrcal_unproject_pinhole(v, nullptr, q, n, intrinsics); return true;
    case Lens::Special::stereographic: mrcal_unproject_stereographic(v, nullptr, q, n, intrinsics); return true;
    case Lens::Special::lonlat: mrcal_unproject_lonlat(v, nullptr, q, n, intrinsics); return true;
    case Lens::Special::latlon: mrcal_unproject_latlon(v, nullptr, q, n, intrinsics); return true;
    case Lens::Special::none: break;
  }
  return mrcal_unproject(v, q, n, &lens.model, intrinsics);
}

bool projectable(const Lens& lens, const Vec3& p) {
  return p.allFinite() && p.squaredNorm() > 0 && (lens.can_project_behind_camera || p.z() > 0);
}

mrcal_point3_t to_mrcal(const Vec3& p) {
  mrcal_point3_t m;
  m.xyz[0] = p.x(), m.xyz[1] = p.y(), m.xyz[2] = p.z();
  return m;
}

Vec3 unit_or_nan(const mrcal_point3_t& v) {
  const Vec3 d(v.xyz[0], v.xyz[1], v.xyz[2]);
  const double n = d.norm();
  return (std::isfinite(n) && n > 0) ? Vec3(d / n) : Vec3::Constant(kNaN);
}

void project_chunk(const Lens& lens, const double* intrinsics, std::span<const Vec3> p, std::span<Vec2> q) {
  const std::size_t n = p.size();
  std::vector<mrcal_point3_t> in(n);
  std::vector<mrcal_point2_t> out(n);
  for (std::size_t i = 0; i < n; ++i) in[i] = to_mrcal(projectable(lens, p[i]) ? p[i] : Vec3(0, 0, 1));
  const bool ok = project_raw(lens, intrinsics, in.data(), static_cast<int>(n), out.data(), nullptr);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2 x(out[i].xy[0], out[i].xy[1]);
    q[i] = (ok && projectable(lens, p[i]) && x.allFinite()) ? x : Vec2::Constant(kNaN);
  }
}

void unproject_chunk(const Lens& lens, const double* intrinsics, std::span<const Vec2> q, std::span<Vec3> v) {
  const std::size_t n = q.size();
  std::vector<mrcal_point2_t> in(n);
  std::vector<mrcal_point3_t> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    const bool finite = q[i].allFinite();  // NaN must not reach mrcal (splined models index by it)
    in[i].xy[0] = finite ? q[i].x() : intrinsics[2];
    in[i].xy[1] = finite ? q[i].y() : intrinsics[3];
  }
  const bool ok = unproject_raw(lens, intrinsics, in.data(), static_cast<int>(n), out.data());
  for (std::size_t i = 0; i < n; ++i)
    v[i] = (ok && q[i].allFinite()) ? unit_or_nan(out[i]) : Vec3::Constant(kNaN);
}

}  // namespace

void CameraModel::project(std::span<const Vec3> points_in_cam, std::span<Vec2> pixels) const {
  if (points_in_cam.size() != pixels.size())
    throw std::invalid_argument("CameraModel::project: points and pixels differ in size");
  const Lens lens = detail::lens_or_throw(lensmodel);
  const double* intr = checked_intrinsics(*this, lens);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points_in_cam.size(), kProjectGrain), [&](const auto& r) {
    project_chunk(lens, intr, points_in_cam.subspan(r.begin(), r.size()), pixels.subspan(r.begin(), r.size()));
  });
}

std::vector<Vec2> CameraModel::project(std::span<const Vec3> points_in_cam) const {
  std::vector<Vec2> out(points_in_cam.size());
  project(points_in_cam, out);
  return out;
}

Vec2 CameraModel::project(const Vec3& point_in_cam) const {
  Vec2 out;
  project(std::span<const Vec3>(&point_in_cam, 1), std::span<Vec2>(&out, 1));
  return out;
}

void CameraModel::unproject(std::span<const Vec2> pixels, std::span<Vec3> rays) const {
  if (pixels.size() != rays.size()) throw std::invalid_argument("CameraModel::unproject: pixels and rays differ in size");
  const Lens lens = detail::lens_or_throw(lensmodel);
  const double* intr = checked_intrinsics(*this, lens);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pixels.size(), kUnprojectGrain), [&](const auto& r) {
    unproject_chunk(lens, intr, pixels.subspan(r.begin(), r.size()), rays.subspan(r.begin(), r.size()));
  });
}

std::vector<Vec3> CameraModel::unproject(std::span<const Vec2> pixels) const {
  std::vector<Vec3> out(pixels.size());
  unproject(pixels, out);
  return out;
}

Vec3 CameraModel::unproject(const Vec2& pixel) const {
  Vec3 out;
  unproject(std::span<const Vec2>(&pixel, 1), std::span<Vec3>(&out, 1));
  return out;
}

void UnprojectImageOptions::validate() const {
  if (coarse_step_px < 1)
    throw std::invalid_argument("UnprojectImageOptions.coarse_step_px = " + std::to_string(coarse_step_px) +
                                ": must be >= 1");
  if (max_newton_steps < 1)
    throw std::invalid_argument("UnprojectImageOptions.max_newton_steps = " + std::to_string(max_newton_steps) +
                                ": must be >= 1");
  if (!(tolerance_px > 0) || !std::isfinite(tolerance_px))
    throw std::invalid_argument("UnprojectImageOptions.tolerance_px = " + std::to_string(tolerance_px) +
                                ": must be a positive number");
}

namespace {

// Where a sample coordinate falls among the coarse nodes: between node k and
// k1 at fraction t.
struct Cell {
  int k = 0, k1 = 0;
  double t = 0;
};

std::vector<double> coarse_nodes(int extent, int step) {
  std::vector<double> nodes;
  for (int x = 0; x < extent; x += step) nodes.push_back(x);
  if (nodes.back() != extent - 1) nodes.push_back(extent - 1);
  return nodes;
}

// One sample of the Newton route: the target pixel, the current ray v (not
// unit), the tangent basis at the start, and the inverse 2x2 Jacobian.
struct Sample {
  Vec3 v, e1, e2;
  Vec2 target, residual;
  Eigen::Matrix2d a_inv;
  enum : unsigned char { active, done, fallback } state;
};

// Per-thread buffers, reused from block to block.
struct Scratch {
  std::vector<Sample> samples;
  std::vector<std::uint32_t> ids;
  std::vector<mrcal_point3_t> p, dq_dp;
  std::vector<mrcal_point2_t> q;
};

// Newton refinement of the samples in `s.samples` (starts and targets filled
// in). Writes converged unit rays to rays[first + k] and returns the others'
// indices (first + k) for the exact route.
void refine_block(const Lens& lens, const double* intrinsics, const UnprojectImageOptions& opt, Scratch& s,
                  std::span<Vec3> rays, std::size_t first, std::vector<std::size_t>& exact) {
  auto& samples = s.samples;
  const std::size_t n = samples.size();
  s.p.resize(n);
  s.q.resize(n);
  s.dq_dp.resize(2 * n);
  s.ids.clear();
  const double tol2 = opt.tolerance_px * opt.tolerance_px;

  // Projects the listed samples; marks converged ones done and non-finite ones
  // fallback; with `gradient`, also forms each inverse Jacobian in the sample's
  // tangent plane (steps stay in that plane: projection ignores scale).
  auto evaluate = [&](bool gradient) {
    const std::size_t m = s.ids.size();
    for (std::size_t k = 0; k < m; ++k) s.p[k] = to_mrcal(samples[s.ids[k]].v);
    const bool ok = project_raw(lens, intrinsics, s.p.data(), static_cast<int>(m), s.q.data(),
                                gradient ? s.dq_dp.data() : nullptr);
    for (std::size_t k = 0; k < m; ++k) {
      Sample& x = samples[s.ids[k]];
      const Vec2 qk(s.q[k].xy[0], s.q[k].xy[1]);
      if (!ok || !qk.allFinite()) {
        x.state = Sample::fallback;
        continue;
      }
      x.residual = x.target - qk;
      if (gradient) {
        const Vec3 jx(s.dq_dp[2 * k].xyz), jy(s.dq_dp[2 * k + 1].xyz);
        Eigen::Matrix2d a;
        a << jx.dot(x.e1), jx.dot(x.e2), jy.dot(x.e1), jy.dot(x.e2);
        const double det = a.determinant();
        if (!std::isfinite(det) || std::abs(det) < 1e-300) {
          x.state = Sample::fallback;
          continue;
        }
        x.a_inv = a.inverse();
      }
      if (x.residual.squaredNorm() <= tol2) x.state = Sample::done;
    }
  };
  auto drop_inactive = [&] {
    std::erase_if(s.ids, [&](std::uint32_t id) { return samples[id].state != Sample::active; });
  };

  for (std::size_t i = 0; i < n; ++i) {
    Sample& x = samples[i];
    x.state = Sample::active;
    if (!x.v.allFinite() || !projectable(lens, x.v)) {
      x.state = Sample::fallback;
      continue;
    }
    const Vec3 helper = std::abs(x.v.y()) < 0.9 ? Vec3::UnitY() : Vec3::UnitX();
    x.e1 = helper.cross(x.v).normalized();
    x.e2 = x.v.cross(x.e1);
    s.ids.push_back(static_cast<std::uint32_t>(i));
  }
  evaluate(true);
  for (int step = 0; step < opt.max_newton_steps; ++step) {
    drop_inactive();
    if (s.ids.empty()) break;
    for (std::uint32_t id : s.ids) {
      Sample& x = samples[id];
      const Vec2 d = x.a_inv * x.residual;
      x.v += d.x() * x.e1 + d.y() * x.e2;
      if (!projectable(lens, x.v)) x.state = Sample::fallback;
    }
    drop_inactive();
    evaluate(false);
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (samples[i].state == Sample::done)
      rays[first + i] = samples[i].v.normalized();
    else
      exact.push_back(first + i);
  }
}

}  // namespace

RayGrid unproject_image(const CameraModel& model, int stride, const UnprojectImageOptions& options) {
  if (stride < 1) throw std::invalid_argument("unproject_image: stride = " + std::to_string(stride) + ", must be >= 1");
  options.validate();
  if (model.width <= 0 || model.height <= 0)
    throw std::invalid_argument("unproject_image: the model has no imager size");
  const Lens lens = detail::lens_or_throw(model.lensmodel);
  checked_intrinsics(model, lens);

  RayGrid grid;
  grid.stride = stride;
  grid.width = (model.width + stride - 1) / stride;
  grid.height = (model.height + stride - 1) / stride;
  grid.intrinsics_hash = model.intrinsics_hash();
  const std::size_t count = static_cast<std::size_t>(grid.width) * grid.height;
  grid.rays.resize(count);
  if (options.method == UnprojectMethod::coarse_grid_newton && !lens.has_gradients)
    throw std::invalid_argument("unproject_image: " + model.lensmodel + " has no gradients; use the exact method");
  std::vector<Vec2> pixels(count);
  for (int j = 0; j < grid.height; ++j)
    for (int i = 0; i < grid.width; ++i) pixels[static_cast<std::size_t>(j) * grid.width + i] = grid.pixel(i, j);
  // exact: mrcal (or the closed form) everywhere; else the coarse grid and Newton per sample.
  grid.exact_fallbacks = PixelUnprojector(model, options).unproject(pixels, grid.rays);
  return grid;
}

PixelUnprojector::PixelUnprojector(const CameraModel& model, const UnprojectImageOptions& options)
    : model_(model), options_(options) {
  options.validate();
  if (model.width <= 0 || model.height <= 0)
    throw std::invalid_argument("PixelUnprojector: the model has no imager size");
  const Lens lens = detail::lens_or_throw(model.lensmodel);
  checked_intrinsics(model, lens);
  newton_ = options.method != UnprojectMethod::exact && lens.special == Lens::Special::none && lens.has_gradients;
  if (!newton_) return;
  xs_ = coarse_nodes(model.width, options.coarse_step_px);
  ys_ = coarse_nodes(model.height, options.coarse_step_px);
  std::vector<Vec2> nodes;
  nodes.reserve(xs_.size() * ys_.size());
  for (double y : ys_)
    for (double x : xs_) nodes.emplace_back(x, y);
  coarse_ = model.unproject(nodes);
}

int PixelUnprojector::unproject(std::span<const Vec2> pixels, std::span<Vec3> rays) const {
  if (pixels.size() != rays.size()) throw std::invalid_argument("PixelUnprojector::unproject: size mismatch");
  if (!newton_) {
    model_.unproject(pixels, rays);
    return 0;
  }
  const Lens lens = detail::lens_or_throw(model_.lensmodel);
  const double* intr = model_.intrinsics.data();
  const int step = options_.coarse_step_px;
  auto cell = [step](const std::vector<double>& nodes, double x) {
    const int last = static_cast<int>(nodes.size()) - 1;
    Cell c;
    c.k = std::clamp(static_cast<int>(std::floor(x)) / step, 0, std::max(last - 1, 0));
    c.k1 = std::min(c.k + 1, last);
    c.t = c.k1 == c.k ? 0.0 : std::clamp((x - nodes[c.k]) / (nodes[c.k1] - nodes[c.k]), 0.0, 1.0);
    return c;
  };
  auto node = [&](int a, int b) -> const Vec3& { return coarse_[static_cast<std::size_t>(b) * xs_.size() + a]; };
  std::vector<std::size_t> exact;
  std::mutex exact_mutex;
  tbb::enumerable_thread_specific<Scratch> scratch;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pixels.size(), 1024), [&](const auto& r) {
    Scratch& s = scratch.local();
    s.samples.resize(r.size());
    for (std::size_t i = r.begin(); i < r.end(); ++i) {
      const Vec2& q = pixels[i];
      Sample& x = s.samples[i - r.begin()];
      x.target = q;
      if (!q.allFinite()) {
        x.v = Vec3::Constant(kNaN);  // refine_block hands it to the exact route
        continue;
      }
      const Cell a = cell(xs_, q.x()), b = cell(ys_, q.y());
      x.v = ((1 - a.t) * (1 - b.t) * node(a.k, b.k) + a.t * (1 - b.t) * node(a.k1, b.k) +
             (1 - a.t) * b.t * node(a.k, b.k1) + a.t * b.t * node(a.k1, b.k1))
                .normalized();  // NaN corners stay NaN
    }
    std::vector<std::size_t> mine;
    refine_block(lens, intr, options_, s, rays, r.begin(), mine);
    if (!mine.empty()) {
      std::lock_guard lock(exact_mutex);
      exact.insert(exact.end(), mine.begin(), mine.end());
    }
  });
  if (exact.empty()) return 0;
  std::vector<Vec2> px(exact.size());
  for (std::size_t k = 0; k < exact.size(); ++k) px[k] = pixels[exact[k]];
  const std::vector<Vec3> again = model_.unproject(px);
  for (std::size_t k = 0; k < exact.size(); ++k) rays[exact[k]] = again[k];
  return static_cast<int>(exact.size());
}

}  // namespace clearfit
