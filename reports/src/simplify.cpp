// Simplifying a triangle mesh for the 3D view: OpenMesh's quadric decimater on an
// index buffer (see clearfit/reports/simplify.hpp).
#include <clearfit/reports/simplify.hpp>

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <algorithm>
#include <array>
#include <limits>
#include <mutex>
#include <numeric>
#include <stdexcept>
#include <string>

namespace clearfit::reports {
namespace {

// OpenMesh's triangle mesh with its own halfedge-collapse test. Debian's
// libOpenMeshCore is built with assertions on: its TriConnectivity::is_collapse_ok
// compares property type names (strings) on every property access, which made
// decimating 1M triangles 2-3x slower. The decimater calls Mesh::is_collapse_ok
// through its template parameter, so this one (compiled here, without the
// assertions) takes its place. It is the usual link condition (Dey et al. 1999):
// the edge and its ends are alive and it has a face; no side face would be left
// with two boundary edges (a dangling triangle); the faces' opposite vertices
// differ; an interior edge does not join two boundary vertices; and v0 and v1
// share no neighbour but those opposite vertices.
struct OmMesh : OpenMesh::TriMesh_ArrayKernelT<> {
  bool is_collapse_ok(OpenMesh::HalfedgeHandle h) {
    const OpenMesh::HalfedgeHandle o = opposite_halfedge_handle(h);
    const VertexHandle v0 = from_vertex_handle(h), v1 = to_vertex_handle(h);
    if (status(edge_handle(h)).deleted() || status(v0).deleted() || status(v1).deleted()) return false;
    const bool face_h = !is_boundary(h), face_o = !is_boundary(o);
    if (!face_h && !face_o) return false;
    auto dangling = [&](OpenMesh::HalfedgeHandle x) {
      return is_boundary(opposite_halfedge_handle(next_halfedge_handle(x))) &&
             is_boundary(opposite_halfedge_handle(prev_halfedge_handle(x)));
    };
    VertexHandle vl, vr;
    if (face_h) {
      if (dangling(h)) return false;
      vl = to_vertex_handle(next_halfedge_handle(h));
    }
    if (face_o) {
      if (dangling(o)) return false;
      vr = to_vertex_handle(next_halfedge_handle(o));
    }
    if (vl.is_valid() && vl == vr) return false;
    if (face_h && face_o && is_boundary(v0) && is_boundary(v1)) return false;
    if (stamp_.size() < n_vertices()) stamp_.resize(n_vertices(), 0);
    if (++now_ == 0) {
      std::fill(stamp_.begin(), stamp_.end(), 0u);
      now_ = 1;
    }
    for (VertexHandle w : vv_range(v0)) stamp_[w.idx()] = now_;
    for (VertexHandle w : vv_range(v1))
      if (stamp_[w.idx()] == now_ && w != vl && w != vr) return false;
    return true;
  }

 private:
  std::vector<unsigned> stamp_;  // neighbour marks of the link test
  unsigned now_ = 0;
};

// OpenMesh reports a face it refuses (complex edge, complex vertex) on its
// global omerr stream (std::cerr); library code prints nothing, so the stream
// is off while faces are added. The refused faces are handled by the caller.
class OmErrQuiet {
 public:
  OmErrQuiet() : lock_(mutex()), was_(::omerr().is_enabled()) { ::omerr().disable(); }
  ~OmErrQuiet() {
    if (was_) ::omerr().enable();
  }
  OmErrQuiet(const OmErrQuiet&) = delete;
  OmErrQuiet& operator=(const OmErrQuiet&) = delete;

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  std::lock_guard<std::mutex> lock_;
  bool was_;
};

// The collapse order and veto of the view's decimation:
//  - ModQuadric's area-weighted quadric error (mm⁴);
//  - with colours, + |Δcolour|²·|edge|⁴, Δcolour being v0's colour minus the
//    colour the new faces interpolate at v0's place: a colour error of the
//    whole range counts like a deviation of one edge length over the collapsed
//    area, so flat regions (quadric error 0) lose first the vertices whose
//    colour their neighbours already give;
//  - + 1e-6·|edge|⁴, which only breaks ties among zero-error collapses in
//    favour of short edges: without it flat, even regions collapse in heap
//    order into fans of valence in the hundreds, slow and ugly;
//  - veto: a collapse that turns a remaining face by more than 60° or leaves it
//    without area (ModNormalFlippingT's test, done here on cross products).
template <class MeshT>
class ModViewT : public OpenMesh::Decimater::ModQuadricT<MeshT> {
 public:
  using Self = ModViewT<MeshT>;
  using Handle = OpenMesh::Decimater::ModHandleT<Self>;
  using Base = OpenMesh::Decimater::ModQuadricT<MeshT>;
  using CollapseInfo = typename Base::CollapseInfo;

  explicit ModViewT(MeshT& mesh) : Base(mesh) {}
  void set_colour(std::span<const float> colour, int components) {
    colour_ = colour;
    components_ = components;
  }
  float collapse_priority(const CollapseInfo& ci) override {
    const float quadric = Base::collapse_priority(ci);
    if (quadric < 0) return quadric;
    const MeshT& m = Base::mesh();
    // The new face (v1, b, c) that holds p0 best: most inside, by barycentrics.
    float best_inside = -std::numeric_limits<float>::infinity();
    std::array<float, 3> weight{};
    std::array<int, 3> corner{};
    for (auto h : m.voh_range(ci.v0)) {
      const auto f = m.face_handle(h);
      if (!f.is_valid() || f == ci.fl || f == ci.fr) continue;
      const auto vb = m.to_vertex_handle(h), vc = m.to_vertex_handle(m.next_halfedge_handle(h));
      const auto b = m.point(vb), c = m.point(vc);
      const auto n = (b - ci.p1) % (c - ci.p1);
      const float len2 = n.sqrnorm();
      if (!(len2 > 0) || (n | m.normal(f)) < kMinCos * std::sqrt(len2)) return Base::ILLEGAL_COLLAPSE;
      if (colour_.empty()) continue;
      const auto q = ci.p0;
      const float wb = (((c - q) % (ci.p1 - q)) | n) / len2, wc = (((ci.p1 - q) % (b - q)) | n) / len2;
      const float w1 = 1 - wb - wc, inside = std::min({w1, wb, wc});
      if (inside > best_inside) {
        best_inside = inside;
        weight = {std::max(w1, 0.0f), std::max(wb, 0.0f), std::max(wc, 0.0f)};
        corner = {ci.v1.idx(), vb.idx(), vc.idx()};
      }
    }
    // Colour error at p0: v0's colour against what the new faces interpolate there.
    double dc2 = 1e-6;
    if (!colour_.empty()) {
      float norm = weight[0] + weight[1] + weight[2];
      if (!(norm > 0)) {  // no face to interpolate in: v1's colour
        weight = {1, 0, 0};
        corner[0] = ci.v1.idx();
        norm = 1;
      }
      const float* c0 = &colour_[static_cast<std::size_t>(ci.v0.idx()) * components_];
      for (int k = 0; k < components_; ++k) {
        double interpolated = 0;
        for (int j = 0; j < 3; ++j)
          interpolated += weight[j] / norm * colour_[static_cast<std::size_t>(corner[j]) * components_ + k];
        dc2 += (c0[k] - interpolated) * (c0[k] - interpolated);
      }
    }
    const double l2 = (ci.p0 - ci.p1).sqrnorm();
    return static_cast<float>(quadric + dc2 * l2 * l2);
  }

 private:
  static constexpr float kMinCos = 0.5f;  // cos 60°
  std::span<const float> colour_;
  int components_ = 3;
};

// A colour difference (Euclidean, linear RGB in [0, 1]) that counts as a jump.
constexpr double kColourJump = 0.2;

}  // namespace

SimplifiedTriangles simplify_triangles(std::span<const float> position_mm,
                                       std::span<const std::uint32_t> triangles, std::size_t max_triangles,
                                       std::span<const float> colour, int colour_components) {
  if (position_mm.size() % 3 != 0 || triangles.size() % 3 != 0)
    throw std::invalid_argument("simplify_triangles: positions and triangles must come in threes");
  const std::size_t nv = position_mm.size() / 3, nt = triangles.size() / 3;
  if (!colour.empty() &&
      (colour_components <= 0 || colour.size() != nv * static_cast<std::size_t>(colour_components)))
    throw std::invalid_argument("simplify_triangles: colour must have colour_components floats per vertex");
  for (std::uint32_t i : triangles)
    if (i >= nv)
      throw std::invalid_argument("simplify_triangles: vertex index " + std::to_string(i) + " out of range");
  SimplifiedTriangles out;
  if (nt <= max_triangles) {
    out.triangles.assign(triangles.begin(), triangles.end());
    out.source_face.resize(nt);
    std::iota(out.source_face.begin(), out.source_face.end(), 0u);
    return out;
  }

  // OpenMesh vertex i is input vertex i (nothing is garbage-collected below).
  OmMesh mesh;
  mesh.request_vertex_status();
  mesh.request_edge_status();
  mesh.request_face_status();
  mesh.request_face_normals();
  mesh.reserve(nv, nv + nt, nt);
  for (std::size_t v = 0; v < nv; ++v)
    mesh.add_vertex(OmMesh::Point(position_mm[3 * v], position_mm[3 * v + 1], position_mm[3 * v + 2]));
  std::vector<std::uint32_t> om_face_source;  // OpenMesh face → input triangle
  std::vector<std::uint32_t> refused;         // input triangles kept as they are
  om_face_source.reserve(nt);
  {
    const OmErrQuiet quiet;
    for (std::size_t t = 0; t < nt; ++t) {
      const std::uint32_t a = triangles[3 * t], b = triangles[3 * t + 1], c = triangles[3 * t + 2];
      const bool ok =
          a != b && b != c && a != c &&
          mesh.add_face(OmMesh::VertexHandle(a), OmMesh::VertexHandle(b), OmMesh::VertexHandle(c)).is_valid();
      if (ok)
        om_face_source.push_back(static_cast<std::uint32_t>(t));
      else
        refused.push_back(static_cast<std::uint32_t>(t));
    }
  }
  for (auto v : mesh.vertices())
    if (mesh.is_boundary(v)) mesh.status(v).set_locked(true);
  for (std::uint32_t t : refused)
    for (int k = 0; k < 3; ++k) mesh.status(OmMesh::VertexHandle(triangles[3 * t + k])).set_locked(true);
  // Colour jumps (e.g. seen/unseen, the no-data grey beside the colormap): both
  // ends of an edge whose colours differ by more than kColourJump are locked, so
  // the jump stays where it was instead of being smeared into long spikes.
  if (!colour.empty()) {
    auto jump = [&](std::uint32_t a, std::uint32_t b) {
      double d2 = 0;
      for (int k = 0; k < colour_components; ++k) {
        const double d =
            colour[std::size_t(a) * colour_components + k] - colour[std::size_t(b) * colour_components + k];
        d2 += d * d;
      }
      return d2 > kColourJump * kColourJump;
    };
    for (std::size_t t = 0; t < nt; ++t)
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t a = triangles[3 * t + k], b = triangles[3 * t + (k + 1) % 3];
        if (jump(a, b)) {
          mesh.status(OmMesh::VertexHandle(a)).set_locked(true);
          mesh.status(OmMesh::VertexHandle(b)).set_locked(true);
        }
      }
  }
  mesh.update_face_normals();

  if (max_triangles > refused.size()) {
    OpenMesh::Decimater::DecimaterT<OmMesh> decimater(mesh);
    ModViewT<OmMesh>::Handle module;
    decimater.add(module);
    decimater.module(module).set_colour(colour, colour_components);
    if (!decimater.initialize())
      throw std::logic_error("simplify_triangles: OpenMesh decimater did not initialise");
    decimater.decimate_to_faces(0, max_triangles - refused.size());
  }

  // Surviving faces (the iteration skips deleted ones) and the refused
  // triangles, in input order.
  std::vector<std::pair<std::uint32_t, std::array<std::uint32_t, 3>>> faces;
  faces.reserve(std::min(nt, max_triangles + refused.size()));
  for (auto f : mesh.faces()) {
    std::array<std::uint32_t, 3> corners{};
    int k = 0;
    for (auto v : mesh.fv_range(f)) corners[k++] = static_cast<std::uint32_t>(v.idx());
    faces.push_back({om_face_source[f.idx()], corners});
  }
  for (std::uint32_t t : refused)
    faces.push_back({t, {triangles[3 * t], triangles[3 * t + 1], triangles[3 * t + 2]}});
  std::sort(faces.begin(), faces.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  out.triangles.reserve(3 * faces.size());
  out.source_face.reserve(faces.size());
  for (const auto& [source, corners] : faces) {
    out.triangles.insert(out.triangles.end(), corners.begin(), corners.end());
    out.source_face.push_back(source);
  }
  return out;
}

}  // namespace clearfit::reports
