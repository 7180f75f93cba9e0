#include <clearfit/geometry/normals.hpp>

#include "reliable_normal.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>
#include <string>

namespace clearfit {

void NormalOptions::validate() const {
  if (!(crease_angle_deg >= 0 && crease_angle_deg <= 180))
    throw std::invalid_argument("NormalOptions::crease_angle_deg = " + std::to_string(crease_angle_deg) +
                                ": must be within [0, 180] degrees");
}

Vec3 CornerNormals::interpolate(int face, double b0, double b1, double b2) const {
  const auto& c = corner[face];
  const Vec3 n = b0 * c[0] + b1 * c[1] + b2 * c[2];
  const double len = n.norm();
  return len > 0 ? Vec3(n / len) : c[0];
}

namespace {
int find(std::vector<int>& parent, int i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}
// True when faces fi and fj of a vertex's fan (corners ki and kj at the vertex) share an edge there.
bool share_edge(const Mesh& mesh, int fi, int ki, int fj, int kj) {
  const auto& ti = mesh.faces[fi];
  const auto& tj = mesh.faces[fj];
  return ti[(ki + 1) % 3] == tj[(kj + 2) % 3] || ti[(ki + 2) % 3] == tj[(kj + 1) % 3] ||
         ti[(ki + 1) % 3] == tj[(kj + 1) % 3] || ti[(ki + 2) % 3] == tj[(kj + 2) % 3];
}
// Interior angle of face f at its corner k (radians).
double corner_angle(const Mesh& m, int f, int k) {
  const Vec3 a = m.corner(f, (k + 1) % 3) - m.corner(f, k);
  const Vec3 b = m.corner(f, (k + 2) % 3) - m.corner(f, k);
  return std::atan2(a.cross(b).norm(), a.dot(b));
}
}  // namespace

CornerNormals compute_corner_normals(const Mesh& mesh, const NormalOptions& options) {
  options.validate();
  const int nf = mesh.num_faces(), nv = mesh.num_vertices();
  std::vector<Vec3> face_n(nf);
  for (int f = 0; f < nf; ++f) face_n[f] = detail::reliable_normal(mesh, f);

  // Vertex -> incident (face, corner) in CSR form.
  std::vector<int> start(nv + 1, 0);
  for (const auto& t : mesh.faces)
    for (int v : t) ++start[v + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  std::vector<std::pair<int, int>> inc(start.back());
  std::vector<int> fill(start.begin(), start.end() - 1);
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) inc[fill[mesh.faces[f][k]]++] = {f, k};

  const double cos_crease = std::cos(options.crease_angle_deg * std::numbers::pi / 180.0);
  CornerNormals out;
  out.corner.assign(nf, {Vec3::Zero(), Vec3::Zero(), Vec3::Zero()});
  std::vector<int> parent;
  std::vector<Vec3> sum;
  for (int v = 0; v < nv; ++v) {
    const int b = start[v], e = start[v + 1], n = e - b;
    if (n == 0) continue;
    parent.resize(n);
    std::iota(parent.begin(), parent.end(), 0);
    // Join faces of the fan that share an edge at v and meet at most at the crease angle.
    for (int i = 0; i < n; ++i)
      for (int j = i + 1; j < n; ++j) {
        const auto [fi, ki] = inc[b + i];
        const auto [fj, kj] = inc[b + j];
        if (face_n[fi].isZero() || face_n[fj].isZero() || !share_edge(mesh, fi, ki, fj, kj)) continue;
        if (face_n[fi].dot(face_n[fj]) >= cos_crease - 1e-12) parent[find(parent, i)] = find(parent, j);
      }
    // A degenerate face takes the normal of one neighbour across an edge at v, never bridging two
    // groups: one lying along a crease would otherwise join both sides of it.
    for (int i = 0; i < n; ++i) {
      const auto [fi, ki] = inc[b + i];
      if (!face_n[fi].isZero()) continue;
      for (int j = 0; j < n; ++j) {
        const auto [fj, kj] = inc[b + j];
        if (face_n[fj].isZero() || !share_edge(mesh, fi, ki, fj, kj)) continue;
        parent[i] = find(parent, j);
        break;
      }
    }
    sum.assign(n, Vec3::Zero());
    for (int i = 0; i < n; ++i) {
      const auto [f, k] = inc[b + i];
      const double w = options.weighting == NormalOptions::Weighting::angle ? corner_angle(mesh, f, k)
                                                                              : mesh.face_area(f);
      sum[find(parent, i)] += w * face_n[f];
    }
    for (int i = 0; i < n; ++i) {
      const auto [f, k] = inc[b + i];
      const Vec3& s = sum[find(parent, i)];
      const double len = s.norm();
      out.corner[f][k] = len > 0 ? Vec3(s / len) : face_n[f];
    }
  }
  return out;
}

}  // namespace clearfit
