#include <clearfit/npy.hpp>

#include <clearfit/error.hpp>
#include <clearfit/refraction/inverse_map.hpp>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

namespace clearfit {

void InverseMapOptions::validate() const {
  auto fail = [](const std::string& what) { throw std::invalid_argument("InverseMapOptions::" + what); };
  auto str = [](double v) {
    std::ostringstream s;
    s << v;
    return s.str();
  };
  if (!(texel_mm > 0) || !std::isfinite(texel_mm))
    fail("texel_mm = " + str(texel_mm) + ": must be a finite number > 0");
  if (!(max_step_ratio > 1) || !std::isfinite(max_step_ratio))
    fail("max_step_ratio = " + str(max_step_ratio) + ": must be a finite number > 1");
  if (max_texels <= 0) fail("max_texels = " + std::to_string(max_texels) + ": must be > 0");
  if (uv_min.has_value() != uv_max.has_value()) fail("uv_min, uv_max: give both or neither");
  if (uv_min) {
    if (!uv_min->allFinite())
      fail("uv_min = (" + str(uv_min->x()) + ", " + str(uv_min->y()) + "): must be finite");
    if (!uv_max->allFinite())
      fail("uv_max = (" + str(uv_max->x()) + ", " + str(uv_max->y()) + "): must be finite");
    if ((uv_max->array() < uv_min->array()).any()) fail("uv_max: must be >= uv_min in both coordinates");
  }
}

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
constexpr int kBandRows = 16;  // texel rows per parallel task

double cross(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

// A pixel cell's bilinear patch: uv(s, t) = a + b s + c t + d s t, corners
// p00 = a, p10 = a + b, p01 = a + c, p11 = a + b + c + d, (s, t) in [0, 1]².
struct Patch {
  Vec2 a, b, c, d;
  Vec2 corner[4];   // p00, p10, p11, p01: the boundary in order
  double sign = 0;  // orientation of the boundary (+1 counter-clockwise)

  Patch(const Vec2& p00, const Vec2& p10, const Vec2& p01, const Vec2& p11)
      : a(p00), b(p10 - p00), c(p01 - p00), d(p11 - p10 - p01 + p00), corner{p00, p10, p11, p01} {
    // Strictly convex (all turns one way, none degenerate) → the bilinear map
    // is a bijection with non-vanishing Jacobian on the closed square.
    double turn[4], scale = 0;
    for (int k = 0; k < 4; ++k) {
      const Vec2 e0 = corner[(k + 1) % 4] - corner[k], e1 = corner[(k + 2) % 4] - corner[(k + 1) % 4];
      turn[k] = cross(e0, e1);
      scale = std::max(scale, e0.squaredNorm());
    }
    const double eps = 1e-12 * scale;
    if (turn[0] > eps && turn[1] > eps && turn[2] > eps && turn[3] > eps) sign = 1;
    if (turn[0] < -eps && turn[1] < -eps && turn[2] < -eps && turn[3] < -eps) sign = -1;
  }
  bool convex() const { return sign != 0; }

  // (s, t) of q if q lies in the patch (boundary included, to rounding).
  bool invert(const Vec2& q, double& s, double& t) const {
    for (int k = 0; k < 4; ++k) {
      const Vec2 e = corner[(k + 1) % 4] - corner[k];
      if (sign * cross(e, q - corner[k]) < -1e-12 * e.squaredNorm()) return false;
    }
    const Vec2 r0 = q - a;
    // Newton from the affine guess (d ignored), iterates kept in the square,
    // where the Jacobian does not vanish.
    double det = cross(b, c);
    s = std::clamp(cross(r0, c) / det, 0.0, 1.0);
    t = std::clamp(cross(b, r0) / det, 0.0, 1.0);
    for (int it = 0; it < 30; ++it) {
      const Vec2 r = b * s + c * t + d * (s * t) - r0;
      const Vec2 js = b + d * t, jt = c + d * s;
      det = cross(js, jt);
      const double ds = cross(r, jt) / det, dt = cross(js, r) / det;
      s = std::clamp(s - ds, 0.0, 1.0);
      t = std::clamp(t - dt, 0.0, 1.0);
      if (std::abs(ds) + std::abs(dt) < 1e-13) break;
    }
    const double residual = (b * s + c * t + d * (s * t) - r0).norm();
    if (!(residual <= 1e-9 * (b.norm() + c.norm()))) return false;
    return true;
  }
};

// Bilinear interpolation of a grid quantity at (px, py) (grid units), using
// only the samples with non-zero weight, all of which must be valid.
template <class Value, class IsValid, class Get>
bool bilinear(int w, int h, double px, double py, IsValid is_valid, Get get, Value& out) {
  if (w < 1 || h < 1 || !(px >= 0 && px <= w - 1 && py >= 0 && py <= h - 1)) return false;
  const int x0 = std::min(static_cast<int>(px), std::max(w - 2, 0)),
            y0 = std::min(static_cast<int>(py), std::max(h - 2, 0));
  const double fx = px - x0, fy = py - y0;
  const double wt[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
  const int dx[4] = {0, 1, 0, 1}, dy[4] = {0, 0, 1, 1};
  out = Value::Zero();
  for (int k = 0; k < 4; ++k) {
    if (wt[k] == 0) continue;
    const int x = x0 + dx[k], y = y0 + dy[k];
    if (x >= w || y >= h || !is_valid(x, y)) return false;
    out += wt[k] * get(x, y);
  }
  return true;
}

double quantile(std::vector<float>& v, double q) {
  if (v.empty()) return 0;
  const auto k =
      static_cast<std::size_t>(std::min<double>(v.size() - 1, std::floor(q * static_cast<double>(v.size()))));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

struct CellRef {
  std::uint32_t cell;   // y * W + x of its top-left pixel
  std::int32_t j0, j1;  // texel rows its bounding box spans
};

// The forward map's usable pixels (valid, with chart coordinates) and the
// chart steps between neighbours, which tell continuous cells from cells
// across a discontinuity.
struct ForwardCells {
  const RefractionMap& fwd;
  int W, H;
  std::vector<std::uint8_t> ok;
  Vec2 lo = Vec2::Constant(INFINITY), hi = Vec2::Constant(-INFINITY);  // bounds of the usable chart_uv
  long long n_valid = 0, n_uv = 0;
  std::vector<float> lh, lv;  // chart length of each step right / down; -1 if an end is unusable
  float ratio = 4;

  Vec2 uv_at(int x, int y) const { return fwd.chart_uv[static_cast<std::size_t>(y) * W + x].cast<double>(); }
  bool usable(int x, int y) const { return ok[static_cast<std::size_t>(y) * W + x] != 0; }
  // A step is continuous unless it is longer than `ratio` times both of its
  // usable neighbours along the same line (no usable neighbour: continuous).
  bool step_ok_h(int x, int y) const {
    const std::size_t p = static_cast<std::size_t>(y) * W + x;
    const float l = lh[p];
    const float ref = std::max(x > 0 ? lh[p - 1] : -1.f, x + 2 < W ? lh[p + 1] : -1.f);
    return l >= 0 && (ref < 0 || l <= ratio * ref);
  }
  bool step_ok_v(int x, int y) const {
    const std::size_t p = static_cast<std::size_t>(y) * W + x;
    const float l = lv[p];
    const float ref = std::max(y > 0 ? lv[p - W] : -1.f, y + 2 < H ? lv[p + W] : -1.f);
    return l >= 0 && (ref < 0 || l <= ratio * ref);
  }
  Patch patch_of(int x, int y) const { return Patch(uv_at(x, y), uv_at(x + 1, y), uv_at(x, y + 1), uv_at(x + 1, y + 1)); }
};

// Stage 1: which pixels are usable, and the bounds of their chart coordinates.
void find_usable(ForwardCells& f, const ContactSurface* contact) {
  const RefractionMap& fwd = f.fwd;
  const std::size_t n_pix = static_cast<std::size_t>(f.W) * f.H;
  f.ok.assign(n_pix, 0);
  for (std::size_t p = 0; p < n_pix; ++p) {
    if (fwd.status[p] != PixelStatus::valid) continue;
    ++f.n_valid;
    const Eigen::Vector2f& uv = fwd.chart_uv[p];
    if (!uv.allFinite()) continue;
    if (contact && (fwd.face[p] < 0 || static_cast<std::size_t>(fwd.face[p]) >= contact->component.size() ||
                    contact->component[fwd.face[p]] < 0))
      throw std::invalid_argument("compute_inverse_map: pixel " + std::to_string(p) + " has face " +
                                  std::to_string(fwd.face[p]) + ", not a face of the given contact surface");
    f.ok[p] = 1;
    ++f.n_uv;
    f.lo = f.lo.cwiseMin(uv.cast<double>());
    f.hi = f.hi.cwiseMax(uv.cast<double>());
  }
  if (f.n_valid > 0 && f.n_uv == 0)
    throw std::invalid_argument(
        "compute_inverse_map: the refraction map has no chart coordinates (trace it with TraceScene::chart "
        "set)");
}

// Stage 2: the texel grid (sizes and origin; every texel invalid).
InverseMap texel_grid(const ForwardCells& f, const InverseMapOptions& options) {
  InverseMap m;
  const double t = options.texel_mm;
  m.texel_mm = t;
  Vec2 edge_lo, edge_hi;
  if (options.uv_min) {
    edge_lo = *options.uv_min;
    edge_hi = *options.uv_max;
  } else {
    if (f.n_uv == 0)
      throw InputError("", "refraction map",
                       "no pixel sees the contact surface through the part, so the inverse map is empty",
                       "check the pose (cam_from_part) and the contact selection");
    edge_lo = (f.lo / t).array().floor() * t;
    edge_hi = (f.hi / t).array().ceil() * t;
  }
  const Eigen::Array2d cells = ((edge_hi - edge_lo) / t).array() - 1e-9;
  const double wd = std::max(1.0, std::ceil(cells.x())), hd = std::max(1.0, std::ceil(cells.y()));
  if (wd * hd > static_cast<double>(options.max_texels))
    throw InputError("", "option texel_mm",
                     "a texel grid of " + std::to_string(static_cast<long long>(wd)) + " x " +
                         std::to_string(static_cast<long long>(hd)) + " exceeds max_texels (" +
                         std::to_string(options.max_texels) + ")",
                     "use larger texels or smaller uv bounds");
  m.width = static_cast<int>(wd);
  m.height = static_cast<int>(hd);
  m.uv_origin = edge_lo + Vec2::Constant(t / 2);
  const std::size_t n_tex = static_cast<std::size_t>(m.width) * m.height;
  m.map_x.assign(n_tex, kInvalidPixel);
  m.map_y.assign(n_tex, kInvalidPixel);
  m.valid.assign(n_tex, 0);
  return m;
}

// Stage 3: chart step lengths, then every usable cell classified (continuous,
// convex) and binned by the texel rows it spans, per image row.
std::vector<std::vector<CellRef>> classify_cells(ForwardCells& f, InverseMap& m, const ContactSurface* contact) {
  const int W = f.W, H = f.H;
  const double t = m.texel_mm;
  f.lh.assign(static_cast<std::size_t>(W) * H, -1.f);
  f.lv.assign(static_cast<std::size_t>(W) * H, -1.f);
  tbb::parallel_for(0, H, [&](int y) {
    for (int x = 0; x < W; ++x) {
      if (!f.usable(x, y)) continue;
      const std::size_t p = static_cast<std::size_t>(y) * W + x;
      if (x + 1 < W && f.usable(x + 1, y)) f.lh[p] = static_cast<float>((f.uv_at(x + 1, y) - f.uv_at(x, y)).norm());
      if (y + 1 < H && f.usable(x, y + 1)) f.lv[p] = static_cast<float>((f.uv_at(x, y + 1) - f.uv_at(x, y)).norm());
    }
  });
  std::vector<std::vector<CellRef>> row_cells(H - 1);
  std::atomic<long long> rejected_step{0}, rejected_fold{0};
  tbb::parallel_for(0, H - 1, [&](int y) {
    long long n_step = 0, n_fold = 0;
    for (int x = 0; x + 1 < W; ++x) {
      if (!f.usable(x, y) || !f.usable(x + 1, y) || !f.usable(x, y + 1) || !f.usable(x + 1, y + 1)) continue;
      bool continuous = f.step_ok_h(x, y) && f.step_ok_h(x, y + 1) && f.step_ok_v(x, y) && f.step_ok_v(x + 1, y);
      if (continuous && contact) {
        const std::size_t p = static_cast<std::size_t>(y) * W + x;
        const int c0 = contact->component[f.fwd.face[p]];
        continuous = contact->component[f.fwd.face[p + 1]] == c0 && contact->component[f.fwd.face[p + W]] == c0 &&
                     contact->component[f.fwd.face[p + W + 1]] == c0;
      }
      if (!continuous) {
        ++n_step;
        continue;
      }
      const Patch patch = f.patch_of(x, y);
      if (!patch.convex()) {
        ++n_fold;
        continue;
      }
      double vmin = INFINITY, vmax = -INFINITY;
      for (const Vec2& q : patch.corner) {
        vmin = std::min(vmin, q.y());
        vmax = std::max(vmax, q.y());
      }
      const double j0 = std::max(0.0, std::ceil((vmin - m.uv_origin.y()) / t - 1e-9));
      const double j1 = std::min(m.height - 1.0, std::floor((vmax - m.uv_origin.y()) / t + 1e-9));
      if (j0 > j1) continue;
      row_cells[y].push_back({static_cast<std::uint32_t>(static_cast<std::size_t>(y) * W + x),
                              static_cast<std::int32_t>(j0), static_cast<std::int32_t>(j1)});
    }
    rejected_step += n_step;
    rejected_fold += n_fold;
  });
  m.cells_rejected_step = rejected_step;
  m.cells_rejected_fold = rejected_fold;
  return row_cells;
}

// Stage 4: the cells sorted into bands of texel rows (counting sort, keeping
// image row-major order): band b holds banded[start[b] .. start[b + 1]).
struct Bands {
  std::vector<std::size_t> start;
  std::vector<CellRef> banded;
};
Bands band_cells(std::vector<std::vector<CellRef>>&& row_cells, InverseMap& m) {
  const int n_bands = (m.height + kBandRows - 1) / kBandRows;
  Bands bands;
  std::vector<std::size_t>& start = bands.start;
  start.assign(n_bands + 1, 0);
  long long used = 0;
  for (const auto& row : row_cells)
    for (const CellRef& c : row) {
      ++used;
      for (int b = c.j0 / kBandRows; b <= c.j1 / kBandRows; ++b) ++start[b + 1];
    }
  m.cells_used = used;
  for (int b = 0; b < n_bands; ++b) start[b + 1] += start[b];
  bands.banded.resize(start[n_bands]);
  std::vector<std::size_t> fill(start.begin(), start.end() - 1);
  for (const auto& row : row_cells)
    for (const CellRef& c : row)
      for (int b = c.j0 / kBandRows; b <= c.j1 / kBandRows; ++b) bands.banded[fill[b]++] = c;
  row_cells = {};
  return bands;
}

// Stage 5: rasterise; each band writes only its own texel rows.
void rasterise(const ForwardCells& f, const Bands& bands, InverseMap& m) {
  const int W = f.W;
  const double t = m.texel_mm;
  const int n_bands = static_cast<int>(bands.start.size()) - 1;
  std::atomic<long long> overlap{0};
  tbb::parallel_for(0, n_bands, [&](int b) {
    const int band_lo = b * kBandRows, band_hi = std::min(m.height - 1, band_lo + kBandRows - 1);
    std::vector<std::uint8_t> folded(static_cast<std::size_t>(band_hi - band_lo + 1) * m.width, 0);
    long long n_overlap = 0;
    for (std::size_t k = bands.start[b]; k < bands.start[b + 1]; ++k) {
      const CellRef& c = bands.banded[k];
      const int x = static_cast<int>(c.cell % W), y = static_cast<int>(c.cell / W);
      const Patch patch = f.patch_of(x, y);
      double umin = INFINITY, umax = -INFINITY;
      for (const Vec2& q : patch.corner) {
        umin = std::min(umin, q.x());
        umax = std::max(umax, q.x());
      }
      const int i0 = static_cast<int>(std::max(0.0, std::ceil((umin - m.uv_origin.x()) / t - 1e-9)));
      const int i1 =
          static_cast<int>(std::min(m.width - 1.0, std::floor((umax - m.uv_origin.x()) / t + 1e-9)));
      for (int j = std::max<int>(c.j0, band_lo); j <= std::min<int>(c.j1, band_hi); ++j)
        for (int i = i0; i <= i1; ++i) {
          double s, tt;
          if (!patch.invert(m.uv(i, j), s, tt)) continue;
          const std::size_t q = m.index(i, j);
          const float px = static_cast<float>(x + s), py = static_cast<float>(y + tt);
          if (m.valid[q]) {
            std::uint8_t& fo = folded[static_cast<std::size_t>(j - band_lo) * m.width + i];
            if (!fo && std::hypot(px - m.map_x[q], py - m.map_y[q]) > 1) {
              fo = 1;
              ++n_overlap;
            }
            continue;
          }
          m.map_x[q] = px;
          m.map_y[q] = py;
          m.valid[q] = 1;
        }
    }
    overlap += n_overlap;
  });
  m.texels_overlap = overlap;
  m.error.texels_valid = std::count(m.valid.begin(), m.valid.end(), std::uint8_t(1));
}

// Stage 6: the round trips texel -> pixel -> chart and pixel -> chart -> pixel.
void round_trip_errors(const ForwardCells& f, InverseMap& m) {
  const int W = f.W, H = f.H;
  auto usable = [&](int x, int y) { return f.usable(x, y); };
  auto uv_at = [&](int x, int y) { return f.uv_at(x, y); };
  std::vector<double> row_uv_err(m.height, 0);
  tbb::parallel_for(0, m.height, [&](int j) {
    double worst = 0;
    for (int i = 0; i < m.width; ++i) {
      const std::size_t q = m.index(i, j);
      if (!m.valid[q]) continue;
      Vec2 uv;
      const bool ok_uv = bilinear(W, H, m.map_x[q], m.map_y[q], usable, uv_at, uv);
      worst = std::max(worst,
                       ok_uv ? (uv - m.uv(i, j)).norm() : INFINITY);  // a texel off its cell would be a bug
    }
    row_uv_err[j] = worst;
  });
  m.error.max_uv_um = 1e3 * *std::max_element(row_uv_err.begin(), row_uv_err.end());

  std::vector<float> px_err(static_cast<std::size_t>(W) * H, -1.f);
  auto texel_ok = [&](int i, int j) { return m.valid[m.index(i, j)] != 0; };
  auto texel_px = [&](int i, int j) { return Vec2(m.map_x[m.index(i, j)], m.map_y[m.index(i, j)]); };
  tbb::parallel_for(0, H, [&](int y) {
    for (int x = 0; x < W; ++x) {
      if (!f.usable(x, y)) continue;
      const Vec2 g = (f.uv_at(x, y) - m.uv_origin) / m.texel_mm;
      Vec2 p;
      if (bilinear(m.width, m.height, g.x(), g.y(), texel_ok, texel_px, p))
        px_err[static_cast<std::size_t>(y) * W + x] = static_cast<float>((p - Vec2(x, y)).norm());
    }
  });
  px_err.erase(std::remove(px_err.begin(), px_err.end(), -1.f), px_err.end());
  m.error.pixels_checked = static_cast<long long>(px_err.size());
  if (!px_err.empty()) {
    m.error.max_px = *std::max_element(px_err.begin(), px_err.end());
    m.error.p99_px = quantile(px_err, 0.99);
    m.error.median_px = quantile(px_err, 0.5);
  }
}

}  // namespace

InverseMap compute_inverse_map(const RefractionMap& fwd, const InverseMapOptions& options,
                               const ContactSurface* contact) {
  options.validate();
  const auto t_start = Clock::now();
  const int W = fwd.width, H = fwd.height;
  const std::size_t n_pix = static_cast<std::size_t>(W) * H;
  if (W < 0 || H < 0 || fwd.status.size() != n_pix || fwd.chart_uv.size() != n_pix ||
      fwd.face.size() != n_pix)
    throw std::invalid_argument("compute_inverse_map: the refraction map's arrays do not match its size");
  ForwardCells f{fwd, W, H};
  f.ratio = static_cast<float>(options.max_step_ratio);
  find_usable(f, contact);
  InverseMap m = texel_grid(f, options);
  if (W < 2 || H < 2 || f.n_uv == 0) {
    m.raster_ms = ms_since(t_start);
    return m;
  }
  rasterise(f, band_cells(classify_cells(f, m, contact), m), m);
  m.raster_ms = ms_since(t_start);
  if (!options.compute_errors) return m;
  const auto t_err = Clock::now();
  round_trip_errors(f, m);
  m.error_ms = ms_since(t_err);
  return m;
}

void write_inverse_map_npy(const InverseMap& map, const std::filesystem::path& path) {
  const auto w = static_cast<std::size_t>(map.width);
  npy::write_float32(path, {static_cast<std::size_t>(map.height), w, 2}, [&](std::size_t j, float* out) {
    for (std::size_t i = 0; i < w; ++i) {
      const std::size_t q = j * w + i;
      out[2 * i] = map.valid[q] ? map.map_x[q] : std::numeric_limits<float>::quiet_NaN();
      out[2 * i + 1] = map.valid[q] ? map.map_y[q] : std::numeric_limits<float>::quiet_NaN();
    }
  });
}

}  // namespace clearfit
