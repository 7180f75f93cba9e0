#pragma once
// Private to geometry/src (validate_cgal.cpp, chart_cgal.cpp): the edge table of
// a triangle soup, computed in plain C++ so it works on any input, and the
// conversion of a clean subset of faces to CGAL::Surface_mesh.
#include <clearfit/geometry/mesh.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <string>
#include <vector>

namespace clearfit::detail {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point3 = Kernel::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point3>;

inline Point3 to_point(const Vec3& p) { return {p.x(), p.y(), p.z()}; }

inline bool has_repeated_vertex(const std::array<int, 3>& f) {
  return f[0] == f[1] || f[1] == f[2] || f[0] == f[2];
}

/// Union-find over 0..n-1 with path halving.
struct DisjointSets {
  std::vector<int> parent;
  explicit DisjointSets(int n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  void unite(int a, int b) { parent[find(a)] = find(b); }
};

/// Undirected edges of a set of faces with every face that uses them.
/// Faces with a repeated vertex index must be left out by the caller.
struct EdgeTable {
  struct Use {
    std::uint64_t key;  ///< (min vertex << 32) | max vertex
    int face;           ///< mesh face index
    int corner;         ///< the edge runs from corner `corner` to corner `corner+1` (mod 3)
    bool forward;       ///< the face walks it from the smaller to the larger vertex index
  };
  std::vector<Use> uses;   ///< sorted by key
  std::vector<int> begin;  ///< edge e owns uses[begin[e] .. begin[e+1])

  int edge_count() const { return static_cast<int>(begin.size()) - 1; }
  int use_count(int e) const { return begin[e + 1] - begin[e]; }
  const Use& use(int e, int i) const { return uses[begin[e] + i]; }
  int vertex_a(int e) const { return static_cast<int>(uses[begin[e]].key >> 32); }
  int vertex_b(int e) const { return static_cast<int>(uses[begin[e]].key & 0xffffffffu); }
};

inline EdgeTable build_edge_table(const Mesh& mesh, const std::vector<int>& faces) {
  EdgeTable t;
  t.uses.reserve(3 * faces.size());
  for (int f : faces)
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.faces[f][k], b = mesh.faces[f][(k + 1) % 3];
      const auto lo = static_cast<std::uint64_t>(std::min(a, b)),
                 hi = static_cast<std::uint64_t>(std::max(a, b));
      t.uses.push_back({(lo << 32) | hi, f, k, a < b});
    }
  std::sort(t.uses.begin(), t.uses.end(), [](const EdgeTable::Use& x, const EdgeTable::Use& y) {
    return x.key != y.key ? x.key < y.key : x.face < y.face;
  });
  for (size_t i = 0; i < t.uses.size(); ++i)
    if (i == 0 || t.uses[i].key != t.uses[i - 1].key) t.begin.push_back(static_cast<int>(i));
  t.begin.push_back(static_cast<int>(t.uses.size()));
  return t;
}

/// Surface_mesh of `faces` (vertices renumbered in order of first use; SM face i
/// is faces[i]). Returns false if CGAL rejects a face (non-manifold edge or
/// vertex, or faces walking an edge the same way); `sm` is then unusable.
inline bool to_surface_mesh(const Mesh& mesh, const std::vector<int>& faces, SurfaceMesh& sm,
                            std::vector<int>* mesh_vertex_of = nullptr) {
  sm.clear();
  std::vector<int> local(mesh.vertices.size(), -1);
  std::vector<int> back;
  for (int f : faces)
    for (int v : mesh.faces[f])
      if (local[v] < 0) {
        local[v] = static_cast<int>(back.size());
        back.push_back(v);
        sm.add_vertex(to_point(mesh.vertices[v]));
      }
  for (int f : faces) {
    const auto& c = mesh.faces[f];
    const auto vd = [&](int k) {
      return SurfaceMesh::Vertex_index(static_cast<SurfaceMesh::size_type>(local[c[k]]));
    };
    if (sm.add_face(vd(0), vd(1), vd(2)) == SurfaceMesh::null_face()) return false;
  }
  if (mesh_vertex_of) *mesh_vertex_of = std::move(back);
  return true;
}

/// "17, 40, 52 and 3 more": the first few entries of a list of indices.
inline std::string first_few(const std::vector<int>& list, size_t shown = 5) {
  std::string s;
  for (size_t i = 0; i < list.size() && i < shown; ++i) s += (i ? ", " : "") + std::to_string(list[i]);
  if (list.size() > shown) s += " and " + std::to_string(list.size() - shown) + " more";
  return s;
}

}  // namespace clearfit::detail
