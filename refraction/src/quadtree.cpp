// The quadtree's levels: trace every cell's nodes and checks, decide each
// cell (accept, split, or hand it to the boundary resolver), fill the accepted
// ones, go on with the children.
#include "quadtree.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>

namespace clearfit::refraction_detail {

void refine_quadtree(const MapRun& run) { Quadtree(run).run(); }

Quadtree::Quadtree(const MapRun& run)
    : run_(run), mesh_(*run.scene.mesh), map_(run.map), st_(run.map.stats), box_(run.box), W_(run.map.width),
      adaptive_(run.options.mode == MapOptions::Mode::adaptive), tol_mm_(run.options.tolerance_um * 1e-3),
      accept_mm_(kAcceptFraction * tol_mm_),
      component_(run.scene.contact->component),
      traced_(static_cast<std::size_t>(run.map.width) * run.map.height, kUntouched),
      flat_(run.options.normals == MapOptions::Normals::flat) {
  if (flat_) entry_face_.resize(traced_.size());
}

void Quadtree::trace_pixels(const std::vector<std::uint32_t>& pixels_in) {
  // Distinct untraced pixels, in the callers' order (cell by cell: nearby
  // pixels go into the same chunk, so the casts stay coherent).
  std::vector<std::uint32_t> pixels;
  pixels.reserve(pixels_in.size());
  for (std::uint32_t p : pixels_in)
    if (!traced_[p]) traced_[p] = kQueued, pixels.push_back(p);
  const auto tu = Clock::now();
  run_.rays.ensure(pixels);
  st_.unproject_ms += ms_since(tu);
  // Chunks of up to 256 rays in parallel: rays, two casts, store (distinct
  // pixels: no races); nothing batch-sized besides the pixel list.
  constexpr std::size_t kChunk = 256;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pixels.size(), kChunk), [&](const auto& r) {
    for (std::size_t b = r.begin(); b < r.end(); b += kChunk) {
      const std::size_t n = std::min(kChunk, r.end() - b);
      std::array<Ray, kChunk> first;
      std::array<SkinSample, kChunk> out;
      for (std::size_t i = 0; i < n; ++i) first[i] = run_.first_ray(pixels[b + i]);
      run_.tracer.trace_chunk(std::span(first.data(), n), std::span(out.data(), n));
      for (std::size_t i = 0; i < n; ++i) {
        store(map_, run_.scene, pixels[b + i], out[i]);
        traced_[pixels[b + i]] = kExact;
        if (flat_) entry_face_[pixels[b + i]] = out[i].entry_face;
      }
    }
  });
  st_.traced += static_cast<long long>(pixels.size());
}

// The check pixels: the centres of the cell's four quadrants (at a quarter
// and three quarters of both diagonals; the children's centres when it is
// split) and one more pixel in each quadrant at a place drawn from the cell's
// position (a fixed hash: maps repeat). Checks on a regular lattice alone
// alias with regularly tessellated meshes: facets 16 px wide put every
// lattice check at the same place on its facet, where the kinks the facets
// leave in the map cost the interpolation least (checks within 0.3 µm in a
// cell with errors of 2.7 µm, shell 58 of 6.7k triangles at 640x480).
// Coordinates that fall on node rows or columns are moved off them where a
// side is long enough (a cell 3 px tall at the bound's edge has nodes at 0,
// 1, 3: its checks go to row 2, else they would see nothing between nodes).
Quadtree::Checks Quadtree::checks_of(const Cell& c) const {
  auto mix = [](std::uint64_t h) {  // splitmix64's finaliser
    h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ULL;
    h = (h ^ (h >> 27)) * 0x94d049bb133111ebULL;
    return h ^ (h >> 31);
  };
  const std::uint64_t seed = mix((std::uint64_t(c.x0) << 48) ^ (std::uint64_t(c.y0) << 32) ^
                                 (std::uint64_t(c.x1) << 16) ^ std::uint64_t(c.y1));
  // Along one axis: the quarter point of half `high`, or (draw >= 0) a pixel
  // drawn strictly inside that half; off the nodes if the side allows it.
  auto at = [](int a0, int a1, bool high, std::int64_t draw) {
    const int m = (a0 + a1) / 2, d = (a1 - a0) / 4;
    auto node = [&](int v) { return v == a0 || v == m || v == a1; };
    const int lo = high ? m : a0, hi = high ? a1 : m;
    int v = high ? a1 - d : a0 + d;
    if (draw >= 0 && hi - lo >= 2) v = lo + 1 + static_cast<int>(draw % (hi - lo - 1));
    if (node(v))
      for (int u = high ? a1 - 1 : a0 + 1; u > a0 && u < a1; u += high ? -1 : 1)
        if (!node(u)) return u;
    return v;
  };
  Checks k;
  for (int i = 0; i < kMaxChecks; ++i) {
    const int quadrant = i % 4;
    const bool hx = quadrant == 1 || quadrant == 2, hy = quadrant == 1 || quadrant == 3;
    const std::uint64_t h = mix(seed + static_cast<std::uint64_t>(i));
    const std::int64_t dx = i < 4 ? -1 : static_cast<std::int64_t>(h & 0xffffff);
    const std::int64_t dy = i < 4 ? -1 : static_cast<std::int64_t>((h >> 24) & 0xffffff);
    const int x = at(c.x0, c.x1, hx, dx), y = at(c.y0, c.y1, hy, dy);
    const std::uint32_t p = idx(x, y);
    if (std::find(k.pixel, k.pixel + k.n, p) != k.pixel + k.n) continue;
    k.x[k.n] = x, k.y[k.n] = y, k.pixel[k.n++] = p;
  }
  return k;
}

// A split cell's children have the parent's nodes as corners: a child whose
// corners differ (status or contact component) is crossed by a boundary
// whatever its checks say, so they are not traced.
bool Quadtree::corners_differ(const Cell& c) const {
  const std::uint32_t k[4] = {idx(c.x0, c.y0), idx(c.x1, c.y0), idx(c.x0, c.y1), idx(c.x1, c.y1)};
  const PixelStatus s0 = map_.status[k[0]];
  for (std::uint32_t p : k) {
    if (map_.status[p] != s0) return true;
    if (s0 == PixelStatus::valid && component_[map_.face[p]] != component_[map_.face[k[0]]]) return true;
  }
  return false;
}

void Quadtree::run() {
  RefractionMap& map = map_;
  const int W = W_, H = map.height;
  // Pixels outside the box are reset here; those in it are written when
  // traced or filled.
  tbb::parallel_for(0, H, [&](int y) {
    if (box_.empty() || y < box_.y0 || y > box_.y1) return reset_span(map, map.index(0, y), W);
    reset_span(map, map.index(0, y), box_.x0);
    reset_span(map, map.index(box_.x1 + 1, y), W - 1 - box_.x1);
  });
  if (box_.empty()) return;
  if (run_.scene.chart && !run_.scene.chart->uv.empty()) locator_.emplace(mesh_, *run_.scene.chart);
  const int S = run_.options.grid_step;
  std::vector<Cell> cells;
  for (int y = box_.y0; y < box_.y1 || y == box_.y0; y += S)
    for (int x = box_.x0; x < box_.x1 || x == box_.x0; x += S)
      cells.push_back({x, y, std::min(x + S, box_.x1), std::min(y + S, box_.y1), kTopLevel});
  std::vector<Cell> boundary;
  bool first_level = true;
  while (!cells.empty()) {
    std::vector<std::uint32_t> batch;
    for (const Cell& c : cells) {
      const Nodes q = nodes_of(c);
      batch.insert(batch.end(), q.pixel, q.pixel + q.n);
      if (!done(c) && (first_level || !corners_differ(c))) {
        const Checks k = checks_of(c);
        batch.insert(batch.end(), k.pixel, k.pixel + k.n);
      }
    }
    first_level = false;
    trace_pixels(batch);
    std::vector<char> decision(cells.size(), skip);
    std::vector<double> cell_err(cells.size(), kUnknownErr);
    decide(cells, decision, cell_err);
    std::vector<Cell> next;
    for (std::size_t ci = 0; ci < cells.size(); ++ci) {
      const Cell& c = cells[ci];
      if (decision[ci] == accept_valid) worst_ = std::max(worst_, cell_err[ci]);
      if (decision[ci] == to_resolver) boundary.push_back(c);
      if (decision[ci] != split) continue;
      const int xm = (c.x0 + c.x1) / 2, ym = (c.y0 + c.y1) / 2;
      const bool sx = c.x1 - c.x0 > 1, sy = c.y1 - c.y0 > 1;
      const double e = cell_err[ci];
      if (sx && sy)
        next.insert(next.end(), {{c.x0, c.y0, xm, ym, e}, {xm, c.y0, c.x1, ym, e}, {c.x0, ym, xm, c.y1, e}, {xm, ym, c.x1, c.y1, e}});
      else if (sx) next.insert(next.end(), {{c.x0, c.y0, xm, c.y1, e}, {xm, c.y0, c.x1, c.y1, e}});
      else next.insert(next.end(), {{c.x0, c.y0, c.x1, ym, e}, {c.x0, ym, c.x1, c.y1, e}});
    }
    fill_accepted(cells, decision);
    cells = std::move(next);
  }
  resolve_boundary(boundary);
  st_.max_error_um = worst_ * 1e3;
}

// Decides every cell in parallel: uniformly valid on one contact component
// and (adaptive) within tolerance at both checks → accept_valid; uniformly
// invalid for one reason → accept_invalid; small and crossed by a validity
// boundary → to_resolver; otherwise split.
void Quadtree::decide(const std::vector<Cell>& cells, std::vector<char>& decision,
                      std::vector<double>& cell_err) const {
  tbb::parallel_for(std::size_t(0), cells.size(), [&](std::size_t ci) {
    const Cell& c = cells[ci];
    if (done(c)) return;
    const Nodes q = nodes_of(c);
    const Checks checks = checks_of(c);
    bool checks_valid = true, checks_first = true;
    for (int k = 0; k < checks.n; ++k) {
      checks_valid &= map_.status[checks.pixel[k]] == PixelStatus::valid;
      checks_first &= map_.status[checks.pixel[k]] == map_.status[q.pixel[0]];
    }
    const PixelStatus first = map_.status[q.pixel[0]];
    bool all_valid = true, same_invalid = true;
    for (int k = 0; k < q.n; ++k) {
      const PixelStatus st_k = map_.status[q.pixel[k]];
      all_valid &= st_k == PixelStatus::valid;
      same_invalid &= st_k != PixelStatus::valid && st_k == first;
    }
    if (all_valid) {
      const int comp = component_[map_.face[q.pixel[0]]];
      for (int k = 0; k < q.n; ++k) all_valid &= component_[map_.face[q.pixel[k]]] == comp;
    }
    if (all_valid && checks_valid && flat_) {  // one facet refracts the whole cell
      const std::int32_t f = entry_face_[q.pixel[0]];
      for (int k = 0; k < q.n; ++k) all_valid &= entry_face_[q.pixel[k]] == f;
      for (int k = 0; k < checks.n; ++k) all_valid &= entry_face_[checks.pixel[k]] == f;
    }
    decision[ci] = split;
    if (all_valid && checks_valid) {
      double err = 0;
      for (int k = 0; k < checks.n; ++k) {
        const auto guess = interpolate(q, weights(q, checks.x[k], checks.y[k]));
        err = std::max(err, guess ? (guess->point - map_.skin_point[checks.pixel[k]]).norm() : 1e300);
      }
      cell_err[ci] = err;
      // adaptive: the checks of a cell whose parent had no estimate (some of
      // its nodes or checks invalid: a boundary or a discontinuity nearby),
      // or an error that no smooth map leaves after one split (a jump between
      // two valid branches, a fold, that the child's checks may straddle),
      // are not trusted alone.
      const bool estimated = c.parent_err != kUnknownErr && c.parent_err <= kTrustedParent * tol_mm_;
      if (err < 1e300 && (!adaptive_ || (err <= accept_mm_ && estimated))) decision[ci] = accept_valid;
    } else if (same_invalid && checks_first) {
      decision[ci] = accept_invalid;  // uniformly invalid for the same reason
    } else if (c.x1 - c.x0 <= kResolveCell && c.y1 - c.y0 <= kResolveCell) {
      decision[ci] = to_resolver;  // a small cell that a validity boundary crosses
    }
  });
}

// Fills the accepted cells row by row across cells (long runs along the rows
// write at about twice the memory bandwidth of cell by cell); with a chart
// each pixel is located on the mesh, and the pixels the location misses are
// traced. A pixel belongs to the cell with x0 <= x < x1 and y0 <= y < y1 (or
// on the box's last column/row), so parallel fills never touch the same pixel.
void Quadtree::fill_accepted(const std::vector<Cell>& cells, const std::vector<char>& decision) {
  std::vector<std::size_t> accepted;
  for (std::size_t ci = 0; ci < cells.size(); ++ci)
    if (decision[ci] == accept_valid || decision[ci] == accept_invalid) accepted.push_back(ci);
  fill_accepted_by_rows(cells, decision, accepted);
  if (!locator_) return;
  std::vector<std::uint32_t> retrace;
  for (std::size_t ci = 0; ci < cells.size(); ++ci) {
    if (decision[ci] != accept_valid) continue;
    const Cell& c = cells[ci];
    for (int y = c.y0; y <= c.y1; ++y)
      for (int x = c.x0; x <= c.x1; ++x)
        if (traced_[idx(x, y)] == kRelocate) traced_[idx(x, y)] = kUntouched, retrace.push_back(idx(x, y));
  }
  trace_pixels(retrace);
}

void Quadtree::fill_accepted_by_rows(const std::vector<Cell>& cells, const std::vector<char>& decision,
                                     std::vector<std::size_t>& accepted) {
  if (accepted.empty()) return;
  std::sort(accepted.begin(), accepted.end(), [&](std::size_t a, std::size_t b) {
    return std::pair(cells[a].y0, cells[a].x0) < std::pair(cells[b].y0, cells[b].x0);
  });
  std::vector<DirectFill> prepared(accepted.size());
  tbb::parallel_for(std::size_t(0), accepted.size(), [&](std::size_t k) {
    if (decision[accepted[k]] == accept_valid) prepare_direct(cells[accepted[k]], prepared[k]);
  });
  // Bands: runs of accepted cells with the same first row; one task per row of a band.
  struct RowTask {
    std::size_t begin, end;
    int y;
  };
  std::vector<RowTask> tasks;
  for (std::size_t k = 0; k < accepted.size();) {
    std::size_t e = k;
    int last = cells[accepted[k]].y0;
    while (e < accepted.size() && cells[accepted[e]].y0 == cells[accepted[k]].y0) {
      last = std::max(last, y_end(cells[accepted[e]]));
      ++e;
    }
    for (int y = cells[accepted[k]].y0; y <= last; ++y) tasks.push_back({k, e, y});
    k = e;
  }
  std::atomic<long long> filled{0};
  tbb::parallel_for(std::size_t(0), tasks.size(), [&](std::size_t t) {
    long long n = 0;
    const RowTask& task = tasks[t];
    for (std::size_t k = task.begin; k < task.end; ++k) {
      const Cell& c = cells[accepted[k]];
      if (task.y > y_end(c)) continue;
      if (decision[accepted[k]] == accept_valid) n += fill_direct_row(prepared[k], task.y);
      else fill_invalid_row(c.x0, x_end(c), task.y, map_.status[nodes_of(c).pixel[0]]);
    }
    filled += n;
  });
  st_.interpolated += filled;
}

}  // namespace clearfit::refraction_detail
