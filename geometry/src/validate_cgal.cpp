// Mesh validation and safe repairs. The topology (edges, fans, boundary loops,
// components) is computed in plain C++ on the raw triangle soup so that it works
// on any input; CGAL supplies the exact predicates for self-intersections
// (box_self_intersection_d + Do_intersect_3, as PMP does for meshes, since
// CGAL 5.5 has no soup version), the outward test (orient_to_bound_a_volume,
// which handles nested shells) and an AABB tree for the thickness rays.
#include <clearfit/format.hpp>
#include <clearfit/geometry/validate.hpp>

#include "cgal_surface_mesh.hpp"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Box_intersection_d/Box_with_info_d.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/box_intersection_d.h>

#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace clearfit {
namespace {

using detail::EdgeTable;
using detail::first_few;
using detail::Kernel;
using detail::to_point;

constexpr size_t kMaxListedIntersections = 100;

std::string plural(size_t n, const std::string& one, const std::string& many) {
  return std::to_string(n) + " " + (n == 1 ? one : many);
}

/// Faces with a repeated vertex index, or an area below `relative_area` times the
/// squared bounding-box diagonal.
std::vector<char> degenerate_faces(const Mesh& mesh, double relative_area) {
  const auto [lo, hi] = bounding_box(mesh);
  const double limit = relative_area * (hi - lo).squaredNorm();
  std::vector<char> bad(mesh.num_faces(), 0);
  for (int f = 0; f < mesh.num_faces(); ++f)
    bad[f] = detail::has_repeated_vertex(mesh.faces[f]) || mesh.face_area(f) <= limit;
  return bad;
}

/// Topological facts of the faces that have three distinct vertices.
struct Topology {
  std::vector<int> faces;  ///< the faces considered
  EdgeTable edges;
  int boundary_edges = 0, boundary_loops = 0;
  int non_manifold_edges = 0, non_manifold_vertices = 0;
  int misoriented_edges = 0;  ///< two faces walking an edge the same way
  int components = 0;
  std::vector<int> component;  ///< per mesh face (-1: left out)
};

Topology analyse(const Mesh& mesh) {
  Topology t;
  for (int f = 0; f < mesh.num_faces(); ++f)
    if (!detail::has_repeated_vertex(mesh.faces[f])) t.faces.push_back(f);
  t.edges = detail::build_edge_table(mesh, t.faces);
  const EdgeTable& E = t.edges;

  // Corners (3f + k) joined across every edge at both its ends: the classes of
  // a vertex's corners are its fans. Faces joined across edges: components.
  detail::DisjointSets corners(3 * mesh.num_faces()), pieces(mesh.num_faces());
  auto corner_at = [&](const EdgeTable::Use& u, bool at_start) {
    return 3 * u.face + (at_start ? u.corner : (u.corner + 1) % 3);
  };
  for (int e = 0; e < E.edge_count(); ++e) {
    const int n = E.use_count(e);
    if (n == 1) ++t.boundary_edges;
    if (n > 2) ++t.non_manifold_edges;
    if (n == 2 && E.use(e, 0).forward == E.use(e, 1).forward) ++t.misoriented_edges;
    for (int i = 1; i < n; ++i) {
      const auto &u = E.use(e, 0), &w = E.use(e, i);
      pieces.unite(u.face, w.face);
      // The corner of u at vertex_a is at u's start if u walks forward (a < b).
      corners.unite(corner_at(u, u.forward), corner_at(w, w.forward));
      corners.unite(corner_at(u, !u.forward), corner_at(w, !w.forward));
    }
  }
  // Fans per vertex.
  std::vector<std::vector<int>> fan_roots(mesh.vertices.size());
  for (int f : t.faces)
    for (int k = 0; k < 3; ++k) {
      auto& roots = fan_roots[mesh.faces[f][k]];
      const int r = corners.find(3 * f + k);
      if (std::find(roots.begin(), roots.end(), r) == roots.end()) roots.push_back(r);
    }
  for (const auto& roots : fan_roots) t.non_manifold_vertices += roots.size() > 1;
  // Boundary loops: boundary edges meeting in the same fan of a vertex belong
  // to the same loop.
  std::vector<int> boundary;
  for (int e = 0; e < E.edge_count(); ++e)
    if (E.use_count(e) == 1) boundary.push_back(e);
  detail::DisjointSets loops(static_cast<int>(boundary.size()));
  std::map<int, int> first_at_corner_class;  // corner class -> boundary edge slot
  for (int i = 0; i < static_cast<int>(boundary.size()); ++i) {
    const auto& u = E.use(boundary[i], 0);
    for (bool at_start : {true, false}) {
      auto [it, inserted] = first_at_corner_class.try_emplace(corners.find(corner_at(u, at_start)), i);
      if (!inserted) loops.unite(i, it->second);
    }
  }
  for (int i = 0; i < static_cast<int>(boundary.size()); ++i) t.boundary_loops += loops.find(i) == i;
  // Components.
  t.component.assign(mesh.num_faces(), -1);
  std::map<int, int> id;
  for (int f : t.faces)
    t.component[f] = id.try_emplace(pieces.find(f), static_cast<int>(id.size())).first->second;
  t.components = static_cast<int>(id.size());
  return t;
}

/// For a closed, manifold, consistently oriented mesh: which faces
/// orient_to_bound_a_volume reverses so that every shell bounds the material
/// from outside (nested shells alternate). nullopt if CGAL cannot take the mesh.
std::optional<std::vector<char>> faces_to_reverse_for_outward(const Mesh& mesh, const Topology& t) {
  detail::SurfaceMesh sm;
  if (t.faces.empty() || !detail::to_surface_mesh(mesh, t.faces, sm) || !CGAL::is_closed(sm))
    return std::nullopt;
  // Remember each face's first halfedge target; after reversal the cycle order flips.
  std::vector<std::array<detail::SurfaceMesh::Vertex_index, 3>> before;
  for (auto f : sm.faces()) {
    auto h = sm.halfedge(f);
    before.push_back({sm.target(h), sm.target(sm.next(h)), sm.target(sm.next(sm.next(h)))});
  }
  CGAL::Polygon_mesh_processing::orient_to_bound_a_volume(sm);
  std::vector<char> reverse(mesh.num_faces(), 0);
  size_t i = 0;
  for (auto f : sm.faces()) {
    auto h = sm.halfedge(f);
    const auto& b = before[i];
    // Same orientation iff next(v) in the cycle equals what followed v before.
    const auto v = sm.target(h), w = sm.target(sm.next(h));
    const int k = v == b[0] ? 0 : v == b[1] ? 1 : 2;
    reverse[t.faces[i]] = b[(k + 1) % 3] != w;
    ++i;
  }
  return reverse;
}

bool faces_intersect(const Mesh& mesh, int f, int g) {
  using K = Kernel;
  const auto& a = mesh.faces[f];
  const auto& b = mesh.faces[g];
  int shared = 0, ia = -1, ib = -1;  // ia, ib: corners of one shared vertex
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (a[i] == b[j]) ++shared, ia = i, ib = j;
  const auto P = [&](int v) { return to_point(mesh.vertices[v]); };
  if (shared == 3) return false;  // a duplicate face: reported as such
  if (shared == 2) {
    // Shared edge p-q: they overlap only if coplanar with the third corners on the same side.
    int r = -1, s = -1, p = -1, q = -1;
    for (int i = 0; i < 3; ++i) {
      if (std::find(b.begin(), b.end(), a[i]) == b.end())
        r = a[i];
      else
        (p < 0 ? p : q) = a[i];
      if (std::find(a.begin(), a.end(), b[i]) == a.end()) s = b[i];
    }
    return CGAL::coplanar(P(p), P(q), P(r), P(s)) &&
           CGAL::coplanar_orientation(P(p), P(q), P(r), P(s)) == CGAL::POSITIVE;
  }
  const K::Triangle_3 ta(P(a[0]), P(a[1]), P(a[2])), tb(P(b[0]), P(b[1]), P(b[2]));
  if (shared == 1) {
    // Shared vertex: they cross only if an opposite edge meets the other triangle.
    const K::Segment_3 sa(P(a[(ia + 1) % 3]), P(a[(ia + 2) % 3])), sb(P(b[(ib + 1) % 3]), P(b[(ib + 2) % 3]));
    return CGAL::do_intersect(ta, sb) || CGAL::do_intersect(tb, sa);
  }
  return CGAL::do_intersect(ta, tb);
}

/// Pairs (f, g), f < g, of mesh faces that intersect other than along shared
/// vertices or edges. Degenerate faces are skipped.
std::vector<std::array<int, 2>> self_intersections(const Mesh& mesh, const std::vector<char>& degenerate) {
  using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int>;
  std::vector<Box> boxes;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    if (degenerate[f]) continue;
    CGAL::Bbox_3 bb = to_point(mesh.corner(f, 0)).bbox() + to_point(mesh.corner(f, 1)).bbox() +
                      to_point(mesh.corner(f, 2)).bbox();
    boxes.emplace_back(bb, f);
  }
  std::vector<std::array<int, 2>> pairs;
  CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), [&](const Box& x, const Box& y) {
    if (faces_intersect(mesh, x.info(), y.info()))
      pairs.push_back({std::min(x.info(), y.info()), std::max(x.info(), y.info())});
  });
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

/// Smallest interior angle of a face (degrees).
double min_angle_deg(const Mesh& mesh, int f) {
  double smallest = 180;
  for (int k = 0; k < 3; ++k) {
    const Vec3 u = mesh.corner(f, (k + 1) % 3) - mesh.corner(f, k),
               v = mesh.corner(f, (k + 2) % 3) - mesh.corner(f, k);
    smallest = std::min(smallest, std::atan2(u.cross(v).norm(), u.dot(v)) * 180 / std::numbers::pi);
  }
  return smallest;
}

/// Thickness along the inward normal from each contact face's centroid to the
/// first non-contact face. `reverse` flags faces whose stored orientation is inward.
void measure_thickness(const Mesh& mesh, const ContactSurface& contact, const std::vector<char>& degenerate,
                       const std::vector<char>& reverse, ValidationReport& r) {
  using Tri = Kernel::Triangle_3;
  using Primitive = CGAL::AABB_triangle_primitive<Kernel, std::vector<Tri>::const_iterator>;
  using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, Primitive>>;
  std::vector<Tri> tris;
  for (int f = 0; f < mesh.num_faces(); ++f)
    if (!contact.is_contact[f] && !degenerate[f])
      tris.emplace_back(to_point(mesh.corner(f, 0)), to_point(mesh.corner(f, 1)),
                        to_point(mesh.corner(f, 2)));
  int tried = 0, missed = 0;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  if (!tris.empty()) {
    Tree tree(tris.begin(), tris.end());
    for (int f : contact.faces) {
      if (degenerate[f]) continue;
      ++tried;
      const Vec3 c = (mesh.corner(f, 0) + mesh.corner(f, 1) + mesh.corner(f, 2)) / 3.0;
      const Vec3 inward = (reverse.empty() || !reverse[f] ? -1.0 : 1.0) * mesh.face_normal(f);
      const auto hit = tree.first_intersection(Kernel::Ray_3(to_point(c), to_point(c + inward)));
      if (!hit) {
        ++missed;
        continue;
      }
      double d;
      if (const auto* p = boost::get<Kernel::Point_3>(&hit->first))
        d = std::sqrt(CGAL::squared_distance(*p, to_point(c)));
      else {
        const auto& s = boost::get<Kernel::Segment_3>(hit->first);
        d = std::sqrt(std::min(CGAL::squared_distance(s.source(), to_point(c)),
                               CGAL::squared_distance(s.target(), to_point(c))));
      }
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
  } else {
    tried = missed = static_cast<int>(contact.faces.size());
  }
  if (tried > missed) r.thickness_min_mm = lo, r.thickness_max_mm = hi;
  if (missed > 0)
    r.warnings.push_back(
        plural(missed, "contact face", "contact faces") + " of " + std::to_string(tried) +
        " found no other surface along the inward normal, so the thickness there is unknown");
}

}  // namespace

void ValidationOptions::validate() const {
  auto bad = [](const std::string& what) { throw std::invalid_argument("ValidationOptions: " + what); };
  if (!(sliver_min_angle_deg >= 0 && sliver_min_angle_deg < 60))
    bad("sliver_min_angle_deg = " + std::to_string(sliver_min_angle_deg) + " must be in [0, 60)");
  if (!(degenerate_area_mm2 >= 0 && std::isfinite(degenerate_area_mm2)))
    bad("degenerate_area_mm2 = " + std::to_string(degenerate_area_mm2) + " must be finite and >= 0");
}

bool ValidationReport::ok() const {
  return faces > 0 && closed && consistently_oriented && outward.value_or(false) &&
         degenerate_faces.empty() && duplicate_faces.empty() && non_manifold_edges == 0 &&
         non_manifold_vertices == 0 && self_intersection_count == 0;
}

ValidationReport validate_mesh(const Mesh& mesh, const ContactSurface* contact,
                               const ValidationOptions& options) {
  options.validate();
  mesh.check_consistent();
  if (contact && contact->is_contact.size() != mesh.faces.size())
    throw std::invalid_argument("validate_mesh: contact surface has " +
                                std::to_string(contact->is_contact.size()) + " face flags for a mesh of " +
                                std::to_string(mesh.faces.size()) + " faces");
  ValidationReport r;
  r.vertices = mesh.num_vertices();
  r.faces = mesh.num_faces();
  std::tie(r.bbox_min, r.bbox_max) = bounding_box(mesh);
  r.area_mm2 = surface_area(mesh);
  auto& warn = r.warnings;
  if (mesh.faces.empty()) {
    warn.push_back("the mesh has no faces");
    return r;
  }

  const std::vector<char> degenerate = degenerate_faces(mesh, options.degenerate_area_mm2);
  for (int f = 0; f < mesh.num_faces(); ++f) {
    if (degenerate[f])
      r.degenerate_faces.push_back(mesh.file_face[f]);
    else if (min_angle_deg(mesh, f) < options.sliver_min_angle_deg)
      r.sliver_faces.push_back(mesh.file_face[f]);
  }
  {  // duplicates: the same three vertex indices in any order
    std::map<std::array<int, 3>, int> first;
    for (int f = 0; f < mesh.num_faces(); ++f) {
      auto key = mesh.faces[f];
      std::sort(key.begin(), key.end());
      auto [it, inserted] = first.try_emplace(key, f);
      if (!inserted) r.duplicate_faces.push_back({mesh.file_face[it->second], mesh.file_face[f]});
    }
  }

  const Topology t = analyse(mesh);
  r.closed = t.boundary_edges == 0 && !t.faces.empty();
  r.boundary_loops = t.boundary_loops;
  r.consistently_oriented = t.misoriented_edges == 0;
  r.non_manifold_edges = t.non_manifold_edges;
  r.non_manifold_vertices = t.non_manifold_vertices;
  r.components = t.components;

  std::vector<char> reverse;  // faces to reverse for outward normals, when known
  if (r.closed && r.consistently_oriented && !r.non_manifold_edges && !r.non_manifold_vertices) {
    if (auto rev = faces_to_reverse_for_outward(mesh, t)) {
      reverse = std::move(*rev);
      const auto n = std::count(reverse.begin(), reverse.end(), 1);
      r.outward = n == 0;
      double v = 0;  // divergence theorem with the corrected orientation
      const Vec3 c = 0.5 * (r.bbox_min + r.bbox_max);
      for (int f : t.faces)
        v += (reverse[f] ? -1 : 1) *
             (mesh.corner(f, 0) - c).dot((mesh.corner(f, 1) - c).cross(mesh.corner(f, 2) - c)) / 6.0;
      r.volume_mm3 = v;
    }
  }

  if (options.check_self_intersections) {
    const auto pairs = self_intersections(mesh, degenerate);
    r.self_intersections_checked = true;
    r.self_intersection_count = static_cast<int>(pairs.size());
    for (size_t i = 0; i < pairs.size() && i < kMaxListedIntersections; ++i)
      r.self_intersections.push_back({mesh.file_face[pairs[i][0]], mesh.file_face[pairs[i][1]]});
  }

  if (contact && !contact->faces.empty()) measure_thickness(mesh, *contact, degenerate, reverse, r);

  // Plain words, most serious first.
  if (!r.closed)
    warn.push_back(
        "the surface is open: " + plural(t.boundary_loops, "boundary loop", "boundary loops") +
        " (holes or missing faces), so it does not enclose a volume and refraction through it is undefined");
  if (!r.consistently_oriented)
    warn.push_back("faces are not consistently oriented: on " + plural(t.misoriented_edges, "edge", "edges") +
                   " both neighbouring faces run the same way (repair can fix this)");
  if (r.outward == false)
    warn.push_back("the normals point into the part (the mesh is inside out" +
                   std::string(r.components > 1 ? " in some pieces" : "") + "); repair can reverse them");
  if (r.closed && r.consistently_oriented && !r.outward.has_value() && !r.non_manifold_edges &&
      !r.non_manifold_vertices)
    warn.push_back("could not decide which way is outward (CGAL could not build a surface from the faces)");
  if (r.non_manifold_edges)
    warn.push_back(plural(r.non_manifold_edges, "edge is", "edges are") +
                   " shared by more than two faces (non-manifold)");
  if (r.non_manifold_vertices)
    warn.push_back(plural(r.non_manifold_vertices, "vertex joins", "vertices join") +
                   " separate pieces of surface that touch only at that point (non-manifold)");
  if (!r.degenerate_faces.empty())
    warn.push_back(plural(r.degenerate_faces.size(), "face has", "faces have") +
                   " no area (a repeated or collinear vertex): file faces " + first_few(r.degenerate_faces) +
                   "; repair drops them");
  if (!r.duplicate_faces.empty())
    warn.push_back(plural(r.duplicate_faces.size(), "face duplicates", "faces duplicate") +
                   " another face: file faces " + std::to_string(r.duplicate_faces[0][0]) + " and " +
                   std::to_string(r.duplicate_faces[0][1]) + (r.duplicate_faces.size() > 1 ? ", ..." : ""));
  if (r.self_intersection_count)
    warn.push_back(plural(r.self_intersection_count, "pair", "pairs") +
                   " of faces cut through each other, e.g. file faces " +
                   std::to_string(r.self_intersections[0][0]) + " and " +
                   std::to_string(r.self_intersections[0][1]));
  if (!r.sliver_faces.empty())
    warn.push_back(plural(r.sliver_faces.size(), "face is a sliver", "faces are slivers") +
                   " (an angle below " + significant_digits(options.sliver_min_angle_deg, 3) +
                   "°): file faces " + first_few(r.sliver_faces));
  if (r.components > 1) warn.push_back("the mesh has " + std::to_string(r.components) + " separate pieces");
  {  // unwelded seams: distinct vertices of faces at exactly the same point
    std::vector<int> used;
    for (int f : t.faces) used.insert(used.end(), mesh.faces[f].begin(), mesh.faces[f].end());
    std::sort(used.begin(), used.end());
    used.erase(std::unique(used.begin(), used.end()), used.end());
    auto less = [&](int a, int b) {
      const Vec3 &p = mesh.vertices[a], &q = mesh.vertices[b];
      return std::tie(p.x(), p.y(), p.z()) < std::tie(q.x(), q.y(), q.z());
    };
    std::sort(used.begin(), used.end(), less);
    size_t twins = 0;
    for (size_t i = 1; i < used.size(); ++i) twins += mesh.vertices[used[i]] == mesh.vertices[used[i - 1]];
    if (twins)
      warn.push_back(plural(twins, "vertex sits", "vertices sit") +
                     " exactly on another vertex without being joined to it (an unwelded seam)");
  }
  return r;
}

namespace {

/// Breadth-first walk over edges shared by exactly two faces; returns which
/// faces to flip so every piece is consistent, keeping in each piece the
/// orientation of the larger area. `conflicts` counts edges that stay
/// inconsistent (non-orientable surface).
std::vector<char> flips_for_consistency(const Mesh& mesh, const Topology& t, int& conflicts) {
  const EdgeTable& E = t.edges;
  std::vector<std::vector<std::pair<int, int>>> next(mesh.num_faces());  // (neighbour, edge)
  for (int e = 0; e < E.edge_count(); ++e)
    if (E.use_count(e) == 2) {
      next[E.use(e, 0).face].push_back({E.use(e, 1).face, e});
      next[E.use(e, 1).face].push_back({E.use(e, 0).face, e});
    }
  std::vector<int> parity(mesh.num_faces(), -1);
  std::vector<char> flip(mesh.num_faces(), 0);
  conflicts = 0;
  for (int seed : t.faces) {
    if (parity[seed] >= 0) continue;
    std::vector<int> piece{seed};
    parity[seed] = 0;
    double area[2] = {0, 0};
    for (size_t i = 0; i < piece.size(); ++i) {
      const int f = piece[i];
      area[parity[f]] += mesh.face_area(f);
      for (auto [g, e] : next[f]) {
        // Same walking direction means opposite orientation.
        const bool same = E.use(e, 0).forward == E.use(e, 1).forward;
        const int want = parity[f] ^ (same ? 1 : 0);
        if (parity[g] < 0) {
          parity[g] = want;
          piece.push_back(g);
        } else if (parity[g] != want && f < g) {
          ++conflicts;
        }
      }
    }
    const int minority = area[1] > area[0] ? 0 : 1;
    for (int f : piece) flip[f] = parity[f] == minority;
  }
  return flip;
}

void reverse_faces(Mesh& mesh, const std::vector<char>& flip) {
  for (int f = 0; f < mesh.num_faces(); ++f)
    if (flip[f]) std::swap(mesh.faces[f][1], mesh.faces[f][2]);
}

std::vector<int> flagged_file_faces(const Mesh& mesh, const std::vector<char>& flag) {
  std::vector<int> out;
  for (int f = 0; f < mesh.num_faces(); ++f)
    if (flag[f]) out.push_back(mesh.file_face[f]);
  return out;
}

}  // namespace

std::vector<std::string> repair_mesh(Mesh& mesh, const RepairOptions& options) {
  mesh.check_consistent();
  std::vector<std::string> changes;
  if (options.drop_degenerate) {
    const std::vector<char> bad = degenerate_faces(mesh, ValidationOptions{}.degenerate_area_mm2);
    const std::vector<int> dropped = flagged_file_faces(mesh, bad);
    if (!dropped.empty()) {
      int kept = 0;
      for (int f = 0; f < mesh.num_faces(); ++f) {
        if (bad[f]) continue;
        mesh.faces[kept] = mesh.faces[f];
        mesh.file_face[kept] = mesh.file_face[f];
        if (!mesh.face_group.empty()) mesh.face_group[kept] = mesh.face_group[f];
        ++kept;
      }
      mesh.faces.resize(kept);
      mesh.file_face.resize(kept);
      if (!mesh.face_group.empty()) mesh.face_group.resize(kept);
      changes.push_back("dropped " + plural(dropped.size(), "degenerate face", "degenerate faces") +
                        " (no area, or a repeated vertex): file faces " + first_few(dropped));
    }
  }
  if (!options.orient_consistently && !options.orient_outward) return changes;

  Topology t = analyse(mesh);
  const bool closed = t.boundary_edges == 0 && !t.faces.empty();
  if (options.orient_consistently || (options.orient_outward && closed)) {
    int conflicts = 0;
    const std::vector<char> flip = flips_for_consistency(mesh, t, conflicts);
    const std::vector<int> flipped = flagged_file_faces(mesh, flip);
    if (!flipped.empty()) {
      reverse_faces(mesh, flip);
      changes.push_back("reversed " + plural(flipped.size(), "face", "faces") +
                        " to agree with their neighbours (one orientation per piece): file faces " +
                        first_few(flipped));
      t = analyse(mesh);
    }
    if (conflicts)
      changes.push_back("could not orient " + plural(conflicts, "edge", "edges") +
                        " consistently: the surface is non-orientable or non-manifold there");
  }
  if (options.orient_outward && closed) {
    std::optional<std::vector<char>> flip;
    if (t.misoriented_edges == 0 && t.non_manifold_edges == 0 && t.non_manifold_vertices == 0)
      flip = faces_to_reverse_for_outward(mesh, t);
    if (!flip) {
      changes.push_back(
          "did not orient the normals outward: the mesh is non-manifold or not consistently oriented");
    } else if (const std::vector<int> flipped = flagged_file_faces(mesh, *flip); !flipped.empty()) {
      reverse_faces(mesh, *flip);
      changes.push_back("reversed " + plural(flipped.size(), "face", "faces") +
                        " so the normals point out of the part: file faces " + first_few(flipped));
    }
  }
  return changes;
}

}  // namespace clearfit
