// The boundary resolver. Small cells that a validity boundary crosses are not
// split down to single pixels. Their untraced pixels (kPending) take the
// status of the nearest node as a guess; then, in rounds, every pending pixel
// that is guessed valid or has a 4-neighbour of another status is traced,
// until no pending pixel borders a different status. The boundary is then
// traced on both sides, pixel-exact, and the pending pixels left are invalid
// for the same reason as all their neighbours, or valid behind the traced
// boundary (filled from a least-squares quadratic where it fits).
#include <clearfit/refraction/quadratic_fit.hpp>
#include "quadtree.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>

namespace clearfit::refraction_detail {

void Quadtree::resolve_boundary(const std::vector<Cell>& cells) {
  if (cells.empty()) return;
  const std::vector<std::vector<std::uint32_t>> per_cell = guess_boundary_cells(cells);
  std::vector<std::uint32_t> pending;
  for (const auto& v : per_cell) pending.insert(pending.end(), v.begin(), v.end());
  trace_boundary(pending);
  // The pending pixels left inside the valid region: a least-squares
  // quadratic in (x, y) through the exactly traced valid pixels around the
  // cell (its valid nodes, its checks, the valid side of the traced boundary,
  // the neighbours' nodes), used only where it fits every one of them within
  // the tolerance and they lie on one contact component; otherwise those
  // pixels are traced.
  std::vector<std::vector<std::uint32_t>> untrusted(cells.size());
  std::vector<double> fit_err(cells.size(), 0);
  std::atomic<long long> fitted{0};
  tbb::parallel_for(std::size_t(0), cells.size(), [&](std::size_t ci) {
    std::vector<std::uint32_t> todo;
    for (std::uint32_t p : per_cell[ci])
      if (traced_[p] == kPending && map_.status[p] == PixelStatus::valid) todo.push_back(p);
    if (todo.empty()) return;
    if (flat_) {  // the map jumps at every facet edge: no fit spans them
      untrusted[ci] = std::move(todo);
      return;
    }
    long long n = 0;
    untrusted[ci] = fit_behind(cells[ci], todo, fit_err[ci], n);
    fitted += n;
  });
  st_.interpolated += fitted;
  for (double e : fit_err) worst_ = std::max(worst_, e);
  std::vector<std::uint32_t> rest;
  for (auto& v : untrusted)
    for (std::uint32_t p : v) rest.push_back(p), traced_[p] = kUntouched;
  trace_pixels(rest);
  // The rest are invalid like all their neighbours: every field reset, the guessed status kept.
  std::erase_if(pending, [&](std::uint32_t p) { return traced_[p] != kPending; });
  tbb::parallel_for(std::size_t(0), pending.size(), [&](std::size_t i) {
    const std::uint32_t p = pending[i];
    const PixelStatus s = map_.status[p];
    reset(map_, p);
    map_.status[p] = s;
    traced_[p] = kFilled;
  });
}

// Marks the untraced pixels of each cell pending with the status of their
// nearest node; returns them per cell.
std::vector<std::vector<std::uint32_t>> Quadtree::guess_boundary_cells(const std::vector<Cell>& cells) {
  std::vector<std::vector<std::uint32_t>> per_cell(cells.size());
  tbb::parallel_for(std::size_t(0), cells.size(), [&](std::size_t ci) {
    const Cell& c = cells[ci];
    const Nodes q = nodes_of(c);
    const int xe = x_end(c), ye = y_end(c);
    auto nearest = [](const int* at, int n, int v) {
      int best = 0;
      for (int i = 1; i < n; ++i)
        if (std::abs(v - at[i]) < std::abs(v - at[best])) best = i;
      return best;
    };
    for (int y = c.y0; y <= ye; ++y)
      for (int x = c.x0; x <= xe; ++x)
        if (const std::uint32_t p = idx(x, y); !traced_[p]) {
          traced_[p] = kPending;
          map_.status[p] = map_.status[q.pixel[nearest(q.ay, q.ny, y) * q.nx + nearest(q.ax, q.nx, x)]];
          per_cell[ci].push_back(p);
        }
  });
  return per_cell;
}

// Validity boundaries are resolved; where two invalid reasons meet (a miss
// beside a ray that enters but exits elsewhere, say) the pixels keep their
// nearest node's reason unless exact_reasons: no skin point depends on it.
bool Quadtree::borders_other(std::uint32_t p) const {
  const int W = W_;
  const int x = static_cast<int>(p % W), y = static_cast<int>(p / W);
  const PixelStatus s = map_.status[p];
  auto other = [&](std::uint32_t n) {
    return run_.options.exact_reasons ? map_.status[n] != s
                                      : (map_.status[n] == PixelStatus::valid) != (s == PixelStatus::valid);
  };
  return (x > box_.x0 && other(p - 1)) || (x < box_.x1 && other(p + 1)) || (y > box_.y0 && other(p - W)) ||
         (y < box_.y1 && other(p + W));
}

// Rounds of tracing every pending pixel next to a change of status, until
// none is left; the traced ones leave `pending`.
void Quadtree::trace_boundary(std::vector<std::uint32_t>& pending) {
  std::vector<char> pick;
  while (!pending.empty()) {
    pick.assign(pending.size(), 0);
    tbb::parallel_for(std::size_t(0), pending.size(), [&](std::size_t i) { pick[i] = borders_other(pending[i]); });
    std::vector<std::uint32_t> round;
    for (std::size_t i = 0; i < pending.size(); ++i)
      if (pick[i]) round.push_back(pending[i]), traced_[pending[i]] = kUntouched;
    if (round.empty()) break;
    trace_pixels(round);
    std::erase_if(pending, [&](std::uint32_t p) { return traced_[p] == kExact; });
  }
}

// On the face of the nearest traced valid pixel: the 5x5 neighbourhood
// first, else any known pixel.
std::uint32_t Quadtree::nearest_known(int x, int y, const std::vector<std::uint32_t>& known) const {
  std::uint32_t near = known[0];
  int best = std::numeric_limits<int>::max();
  for (int dy = -2; dy <= 2; ++dy)
    for (int dx = -2; dx <= 2; ++dx) {
      const int xx = x + dx, yy = y + dy;
      if (!box_.contains(xx, yy)) continue;
      const std::uint32_t k = idx(xx, yy);
      if (traced_[k] == kExact && map_.status[k] == PixelStatus::valid && dx * dx + dy * dy < best)
        best = dx * dx + dy * dy, near = k;
    }
  if (best == std::numeric_limits<int>::max())
    for (std::uint32_t k : known) {
      const int dx = static_cast<int>(k % W_) - x, dy = static_cast<int>(k / W_) - y;
      if (dx * dx + dy * dy < best) best = dx * dx + dy * dy, near = k;
    }
  return near;
}

std::vector<std::uint32_t> Quadtree::fit_behind(const Cell& c, const std::vector<std::uint32_t>& todo,
                                                double& fit_err, long long& fitted) {
  const int W = W_;
  constexpr int kMargin = 4;
  const int wx0 = std::max(box_.x0, c.x0 - kMargin), wx1 = std::min(box_.x1, c.x1 + kMargin);
  const int wy0 = std::max(box_.y0, c.y0 - kMargin), wy1 = std::min(box_.y1, c.y1 + kMargin);
  std::vector<std::uint32_t> known;
  for (int y = wy0; y <= wy1; ++y)
    for (int x = wx0; x <= wx1; ++x)
      if (const std::uint32_t p = idx(x, y); traced_[p] == kExact && map_.status[p] == PixelStatus::valid)
        known.push_back(p);
  bool ok = known.size() >= 12;
  const int comp = ok ? component_[map_.face[known[0]]] : -1;
  for (std::size_t k = 0; ok && k < known.size(); ++k) ok = component_[map_.face[known[k]]] == comp;
  constexpr int kCols = 8;  // skin point, incidence, contact, transmittance, chart uv
  using Fit = QuadraticFit<kCols>;
  auto values = [&](std::uint32_t p) {
    Fit::Row r;
    const Eigen::Vector2d uv = locator_ ? Eigen::Vector2d(map_.chart_uv[p].cast<double>()) : Eigen::Vector2d::Zero();
    r << map_.skin_point[p].transpose(), map_.incidence_deg[p], map_.contact_deg[p], map_.transmittance[p], uv.transpose();
    return r;
  };
  Fit fit(0.5 * (c.x0 + c.x1), 0.5 * (c.y0 + c.y1), 1.0 / std::max(1, c.x1 - c.x0));
  if (ok) {
    std::vector<Fit::Row> known_values(known.size());
    for (std::size_t k = 0; k < known.size(); ++k) {
      known_values[k] = values(known[k]);
      fit.add(static_cast<int>(known[k] % W), static_cast<int>(known[k] / W), known_values[k]);
    }
    ok = fit.solve();
    double err = 0;
    for (std::size_t k = 0; ok && k < known.size(); ++k) {
      const std::uint32_t p = known[k];
      const Fit::Row r = fit.at(static_cast<int>(p % W), static_cast<int>(p / W)) - known_values[k];
      err = std::max({err, r.head<3>().norm(), r.tail<2>().norm()});
    }
    ok = ok && std::isfinite(err) && err <= tol_mm_;
    fit_err = ok ? err : 0;
  }
  if (!ok) return todo;
  std::vector<std::uint32_t> untrusted;
  for (std::uint32_t p : todo) {
    const int x = static_cast<int>(p % W), y = static_cast<int>(p / W);
    const Fit::Row v = fit.at(x, y);
    Interp r;
    if (locator_) {
      const Vec2 uv(v[6], v[7]);
      const auto hit = locator_->locate(uv);
      if (!hit) {
        untrusted.push_back(p);
        continue;
      }
      r = Interp{hit->point, hit->face, hit->bary, uv};
    } else {
      r.point = v.head<3>().transpose();
      r.face = map_.face[nearest_known(x, y, known)];
      r.uv = Vec2::Constant(std::numeric_limits<double>::quiet_NaN());
      r.bary = plane_bary(mesh_, r.face, r.point);
    }
    map_.status[p] = PixelStatus::valid;
    map_.skin_point[p] = r.point;
    map_.face[p] = r.face;
    map_.bary[p] = Eigen::Vector2f(static_cast<float>(r.bary[1]), static_cast<float>(r.bary[2]));
    map_.chart_uv[p] = r.uv.cast<float>();
    map_.incidence_deg[p] = static_cast<float>(v[3]);
    map_.contact_deg[p] = static_cast<float>(v[4]);
    map_.transmittance[p] = std::clamp(static_cast<float>(v[5]), 0.0f, 1.0f);
    traced_[p] = kFilled;
    ++fitted;
  }
  return untrusted;
}

}  // namespace clearfit::refraction_detail
