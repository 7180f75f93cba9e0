#include "chart_locator.hpp"

#include <cmath>
#include <limits>

namespace clearfit::refraction_detail {

ChartLocator::ChartLocator(const Mesh& mesh, const Chart& chart) : mesh_(mesh), chart_(chart) {
  if (chart.faces.empty()) return;
  Vec2 hi = chart.uv[mesh.faces[chart.faces[0]][0]];
  lo_ = hi;
  for (int f : chart.faces)
    for (int v : mesh.faces[f]) lo_ = lo_.cwiseMin(chart.uv[v]), hi = hi.cwiseMax(chart.uv[v]);
  const double area = std::max((hi - lo_).prod(), 1e-300);
  cell_ = std::max(std::sqrt(area / static_cast<double>(chart.faces.size())), 1e-12);
  nx_ = std::max(1, static_cast<int>(std::ceil((hi.x() - lo_.x()) / cell_)) + 1);
  ny_ = std::max(1, static_cast<int>(std::ceil((hi.y() - lo_.y()) / cell_)) + 1);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  affine_.assign(mesh.faces.size(), Affine{Vec2::Constant(nan), {nan, nan, nan, nan}});
  for (int f : chart.faces) {
    const auto& t = mesh.faces[f];
    const Vec2 a = chart.uv[t[0]], e1 = chart.uv[t[1]] - a, e2 = chart.uv[t[2]] - a;
    const double det = e1.x() * e2.y() - e1.y() * e2.x();
    if (det != 0) affine_[f] = Affine{a, {e2.y() / det, -e2.x() / det, -e1.y() / det, e1.x() / det}};
  }
  std::vector<std::pair<int, int>> entries;  // (cell, face)
  for (int f : chart.faces) {
    Vec2 a = chart.uv[mesh.faces[f][0]], b = a;
    for (int v : mesh.faces[f]) a = a.cwiseMin(chart.uv[v]), b = b.cwiseMax(chart.uv[v]);
    const int x0 = static_cast<int>((a.x() - lo_.x()) / cell_), x1 = static_cast<int>((b.x() - lo_.x()) / cell_);
    const int y0 = static_cast<int>((a.y() - lo_.y()) / cell_), y1 = static_cast<int>((b.y() - lo_.y()) / cell_);
    for (int y = y0; y <= std::min(y1, ny_ - 1); ++y)
      for (int x = x0; x <= std::min(x1, nx_ - 1); ++x) entries.emplace_back(y * nx_ + x, f);
  }
  start_.assign(static_cast<std::size_t>(nx_) * ny_ + 1, 0);
  for (const auto& e : entries) ++start_[e.first + 1];
  for (std::size_t i = 1; i < start_.size(); ++i) start_[i] += start_[i - 1];
  faces_.resize(entries.size());
  std::vector<int> fill(start_.begin(), start_.end() - 1);
  for (const auto& e : entries) faces_[fill[e.first]++] = e.second;
}

std::optional<ChartHit> ChartLocator::in_face(const Vec2& uv, int f) const {
  const Affine& A = affine_[f];
  const Vec2 r = uv - A.a;
  const double b1 = A.m[0] * r.x() + A.m[1] * r.y(), b2 = A.m[2] * r.x() + A.m[3] * r.y();
  const double b0 = 1 - b1 - b2, tol = -1e-9;
  if (!(b0 >= tol && b1 >= tol && b2 >= tol)) return std::nullopt;  // also a face without an affine (NaN)
  ChartHit h;
  h.face = f;
  h.bary = {b0, b1, b2};
  h.point = b0 * mesh_.corner(f, 0) + b1 * mesh_.corner(f, 1) + b2 * mesh_.corner(f, 2);
  return h;
}

std::optional<ChartHit> ChartLocator::locate(const Vec2& uv) const {
  if (nx_ == 0 || !uv.allFinite()) return std::nullopt;
  const int x = static_cast<int>(std::floor((uv.x() - lo_.x()) / cell_));
  const int y = static_cast<int>(std::floor((uv.y() - lo_.y()) / cell_));
  if (x < 0 || y < 0 || x >= nx_ || y >= ny_) return std::nullopt;
  const int c = y * nx_ + x;
  for (int i = start_[c]; i < start_[c + 1]; ++i)
    if (auto h = in_face(uv, faces_[i])) return h;
  return std::nullopt;
}

std::optional<ChartHit> ChartLocator::locate(const Vec2& uv, int hint) const {
  if (hint >= 0 && uv.allFinite())
    if (auto h = in_face(uv, hint)) return h;
  return locate(uv);
}

}  // namespace clearfit::refraction_detail
