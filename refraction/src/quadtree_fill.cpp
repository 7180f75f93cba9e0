// The quadtree's interpolant and the fills of accepted cells.
#include "quadtree.hpp"

#include <algorithm>

namespace clearfit::refraction_detail {

namespace {

// Lagrange weights w[0..n) of nodes at `at` for the value v; returns the heaviest.
int lagrange(const int* at, int n, int v, double* w) {
  int best = 0;
  for (int i = 0; i < n; ++i) {
    w[i] = 1;
    for (int k = 0; k < n; ++k)
      if (k != i) w[i] *= double(v - at[k]) / (at[i] - at[k]);
    if (w[i] > w[best]) best = i;
  }
  return best;
}

}  // namespace

Quadtree::Nodes Quadtree::nodes_of(const Cell& c) const {
  Nodes q;
  auto axis = [](int a0, int a1, int* at) {
    if (a1 == a0) return at[0] = a0, 1;
    if (a1 - a0 == 1) return at[0] = a0, at[1] = a1, 2;
    return at[0] = a0, at[1] = (a0 + a1) / 2, at[2] = a1, 3;
  };
  q.nx = axis(c.x0, c.x1, q.ax);
  q.ny = axis(c.y0, c.y1, q.ay);
  for (int j = 0; j < q.ny; ++j)
    for (int i = 0; i < q.nx; ++i) q.pixel[q.n++] = idx(q.ax[i], q.ay[j]);
  return q;
}

// Lagrange weights of the nodes at pixel (x, y).
std::array<double, 9> Quadtree::weights(const Nodes& q, int x, int y) {
  std::array<double, 9> w{};
  double wx[3], wy[3];
  for (int i = 0; i < q.nx; ++i) {
    wx[i] = 1;
    for (int k = 0; k < q.nx; ++k)
      if (k != i) wx[i] *= double(x - q.ax[k]) / (q.ax[i] - q.ax[k]);
  }
  for (int j = 0; j < q.ny; ++j) {
    wy[j] = 1;
    for (int k = 0; k < q.ny; ++k)
      if (k != j) wy[j] *= double(y - q.ay[k]) / (q.ay[j] - q.ay[k]);
  }
  for (int j = 0; j < q.ny; ++j)
    for (int i = 0; i < q.nx; ++i) w[j * q.nx + i] = wx[i] * wy[j];
  return w;
}

std::optional<Quadtree::Interp> Quadtree::interpolate(const Nodes& q, const std::array<double, 9>& w, int hint) const {
  int heaviest = 0;
  for (int k = 0; k < q.n; ++k)
    if (w[k] > w[heaviest]) heaviest = k;
  if (locator_) {
    Vec2 uv = Vec2::Zero();
    for (int k = 0; k < q.n; ++k) uv += w[k] * map_.chart_uv[q.pixel[k]].cast<double>();
    const auto hit = locator_->locate(uv, hint);
    if (!hit) return std::nullopt;
    return Interp{hit->point, hit->face, hit->bary, uv};
  }
  Interp r{Vec3::Zero(), map_.face[q.pixel[heaviest]], {}, Vec2::Constant(std::numeric_limits<double>::quiet_NaN())};
  for (int k = 0; k < q.n; ++k) r.point += w[k] * map_.skin_point[q.pixel[k]];
  r.bary = plane_bary(mesh_, r.face, r.point);
  return r;
}

void Quadtree::prepare_direct(const Cell& c, DirectFill& f) const {
  f.q = nodes_of(c);
  const Nodes& q = f.q;
  f.x0 = c.x0, f.y0 = c.y0;
  f.xe = x_end(c), f.ye = y_end(c);
  for (int k = 0; k < q.n; ++k) {
    DirectFill::Frame& fr = f.frame[k];
    const std::uint32_t n = q.pixel[k];
    fr.face = map_.face[n];
    fr.a = mesh_.corner(fr.face, 0);
    const Vec3 e1 = mesh_.corner(fr.face, 1) - fr.a, e2 = mesh_.corner(fr.face, 2) - fr.a;
    const double d11 = e1.dot(e1), d12 = e1.dot(e2), d22 = e2.dot(e2), det = d11 * d22 - d12 * d12;
    const double inv = det > 0 ? 1 / det : 0;
    fr.g1 = (d22 * e1 - d12 * e2) * inv;
    fr.g2 = (d11 * e2 - d12 * e1) * inv;
    if (locator_)  // chart coordinates in place of the point
      f.node_val[k] << map_.chart_uv[n].cast<double>(), 0.0, map_.incidence_deg[n], map_.contact_deg[n], map_.transmittance[n];
    else
      f.node_val[k] << map_.skin_point[n], map_.incidence_deg[n], map_.contact_deg[n], map_.transmittance[n];
  }
  for (int k = 0; k < 3; ++k) lagrange(q.ax, q.nx, f.x0 + k, f.wx0[k]);
  f.ix_n = 0;
  for (int x = f.x0; x <= f.xe; ++x) {
    double w[3];
    const int ix = lagrange(q.ax, q.nx, x, w);
    if (f.ix_n == 0 || f.ix_of[f.ix_n - 1] != ix) f.ix_from[f.ix_n] = x - f.x0, f.ix_of[f.ix_n++] = ix;
  }
}

// Row y of a prepared cell. Along a row the interpolant is a polynomial of
// degree nx - 1 <= 2 in x: values at x0, x0 + 1, x0 + 2, then forward
// differences.
long long Quadtree::fill_direct_row(const DirectFill& f, int y) {
  using Val = DirectFill::Val;
  const Nodes& q = f.q;
  double wy[3];
  const int jy = lagrange(q.ay, q.ny, y, wy);
  Val row[3];
  for (int i = 0; i < q.nx; ++i) {
    row[i].setZero();
    for (int j = 0; j < q.ny; ++j) row[i] += wy[j] * f.node_val[j * q.nx + i];
  }
  Val v[3];
  for (int k = 0; k < 3; ++k) {
    v[k].setZero();
    for (int i = 0; i < q.nx; ++i) v[k] += f.wx0[k][i] * row[i];
  }
  // Forward differences of the values and, per run of one heaviest node
  // column, of the two barycentric weights (linear in the point).
  using Val8 = Eigen::Matrix<double, 8, 1>;
  Val8 value, d1, d2;
  value << v[0], 0, 0;
  d1 << v[1] - v[0], 0, 0;
  d2 << v[2] - 2 * v[1] + v[0], 0, 0;
  const std::uint32_t row_start = idx(f.x0, y);
  long long count = 0;
  const int n = f.xe - f.x0 + 1;
  if (locator_) {  // chart coordinates located on the mesh, the previous pixel's face tried first
    int hint = -1;
    for (int xi = 0; xi < n; ++xi, value += d1, d1 += d2) {
      const std::uint32_t p = row_start + static_cast<std::uint32_t>(xi);
      if (traced_[p]) continue;
      const Vec2 uv = value.head<2>();
      const auto hit = locator_->locate(uv, hint);
      if (!hit) {
        traced_[p] = kRelocate;
        continue;
      }
      hint = hit->face;
      traced_[p] = kFilled;
      map_.status[p] = PixelStatus::valid;
      map_.skin_point[p] = hit->point;
      map_.face[p] = hit->face;
      map_.bary[p] = Eigen::Vector2f(static_cast<float>(hit->bary[1]), static_cast<float>(hit->bary[2]));
      map_.chart_uv[p] = uv.cast<float>();
      map_.incidence_deg[p] = static_cast<float>(value[3]);
      map_.contact_deg[p] = static_cast<float>(value[4]);
      map_.transmittance[p] = std::clamp(static_cast<float>(value[5]), 0.0f, 1.0f);
      ++count;
    }
    return count;
  }
  for (int seg = 0; seg < f.ix_n; ++seg) {
    const DirectFill::Frame& fr = f.frame[jy * q.nx + f.ix_of[seg]];
    const int xi_end = seg + 1 < f.ix_n ? f.ix_from[seg + 1] : n;
    value[6] = (value.head<3>() - fr.a).dot(fr.g1), value[7] = (value.head<3>() - fr.a).dot(fr.g2);
    d1[6] = d1.head<3>().dot(fr.g1), d1[7] = d1.head<3>().dot(fr.g2);
    d2[6] = d2.head<3>().dot(fr.g1), d2[7] = d2.head<3>().dot(fr.g2);
    for (int xi = f.ix_from[seg]; xi < xi_end; ++xi, value += d1, d1 += d2) {
      const std::uint32_t p = row_start + static_cast<std::uint32_t>(xi);
      if (traced_[p]) continue;
      traced_[p] = kFilled;
      map_.status[p] = PixelStatus::valid;
      map_.skin_point[p] = value.head<3>();
      map_.face[p] = fr.face;
      map_.bary[p] = Eigen::Vector2f(static_cast<float>(value[6]), static_cast<float>(value[7]));
      map_.chart_uv[p] = Eigen::Vector2f(fnan, fnan);
      map_.incidence_deg[p] = static_cast<float>(value[3]);
      map_.contact_deg[p] = static_cast<float>(value[4]);
      map_.transmittance[p] = std::clamp(static_cast<float>(value[5]), 0.0f, 1.0f);
      ++count;
    }
  }
  return count;
}

// Row y of a cell that is uniformly invalid for reason `why`: runs of
// untraced pixels, a field at a time.
void Quadtree::fill_invalid_row(int x0, int xe, int y, PixelStatus why) {
  for (int x = x0; x <= xe;) {
    if (traced_[idx(x, y)]) {
      ++x;
      continue;
    }
    int run = 1;
    while (x + run <= xe && !traced_[idx(x + run, y)]) ++run;
    reset_span(map_, idx(x, y), run, why);
    std::fill_n(traced_.begin() + idx(x, y), run, kFilled);
    x += run;
  }
}

}  // namespace clearfit::refraction_detail
