// The 2D metric chart of the contact surface: an exact orthogonal projection
// when the surface is flat, else CGAL Surface_mesh_parameterization (LSCM or
// ARAP) per connected component, scaled so 2D area equals 3D area.
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>
#include <clearfit/geometry/chart.hpp>

#include "cgal_surface_mesh.hpp"

#include <CGAL/Surface_mesh_parameterization/ARAP_parameterizer_3.h>
#include <CGAL/Surface_mesh_parameterization/LSCM_parameterizer_3.h>
#include <CGAL/Surface_mesh_parameterization/parameterize.h>

#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace clearfit {
namespace {

namespace SMP = CGAL::Surface_mesh_parameterization;
using detail::first_few;
using detail::SurfaceMesh;

/// Right-handed signed area of the 2D triangle (a, b, c).
double signed_area(const Vec2& a, const Vec2& b, const Vec2& c) {
  const Vec2 u = b - a, v = c - a;
  return 0.5 * (u.x() * v.y() - u.y() * v.x());
}

/// Flips the sign of a unit vector so its largest-magnitude component is positive.
Vec3 canonical_sign(const Vec3& d) {
  Eigen::Index i;
  d.cwiseAbs().maxCoeff(&i);
  return d[i] < 0 ? Vec3(-d) : d;
}

std::vector<int> used_vertices(const Mesh& mesh, const std::vector<int>& faces) {
  std::vector<int> v;
  for (int f : faces) v.insert(v.end(), mesh.faces[f].begin(), mesh.faces[f].end());
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

struct Plane {
  Vec3 centre, normal, axis_u, axis_v;
  double max_distance = 0;
};

/// Least-squares plane of the contact vertices (PCA). The normal points to the
/// side the contact faces face (area-weighted); axis_u is the main in-plane
/// axis, or, when the in-plane spread is isotropic, the projection of the
/// coordinate axis most parallel to the plane; axis_v = normal × axis_u.
Plane fit_plane(const Mesh& mesh, const std::vector<int>& faces, const std::vector<int>& verts) {
  Plane p;
  p.centre = Vec3::Zero();
  for (int v : verts) p.centre += mesh.vertices[v];
  p.centre /= static_cast<double>(verts.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (int v : verts) {
    const Vec3 d = mesh.vertices[v] - p.centre;
    cov += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  p.normal = eig.eigenvectors().col(0);
  Vec3 facing = Vec3::Zero();
  for (int f : faces) facing += mesh.face_cross(f);
  if (p.normal.dot(facing) < 0) p.normal = -p.normal;
  const Vec3 lambda = eig.eigenvalues();
  Vec3 u;
  if (lambda[2] - lambda[1] > 1e-6 * lambda[2]) {
    u = eig.eigenvectors().col(2);
  } else {
    Eigen::Index i;
    p.normal.cwiseAbs().minCoeff(&i);
    u = Vec3::Unit(i) - p.normal[i] * p.normal;
  }
  p.axis_u = canonical_sign(u.normalized());
  p.axis_v = p.normal.cross(p.axis_u);
  for (int v : verts)
    p.max_distance = std::max(p.max_distance, std::abs((mesh.vertices[v] - p.centre).dot(p.normal)));
  return p;
}

/// Edge-connected pieces of the given faces, each in ascending face order,
/// ordered by their first face.
std::vector<std::vector<int>> components(const Mesh& mesh, const std::vector<int>& faces,
                                         const detail::EdgeTable& edges) {
  detail::DisjointSets sets(mesh.num_faces());
  for (int e = 0; e < edges.edge_count(); ++e)
    for (int i = 1; i < edges.use_count(e); ++i) sets.unite(edges.use(e, 0).face, edges.use(e, i).face);
  std::vector<std::vector<int>> out;
  std::vector<int> slot(mesh.num_faces(), -1);
  for (int f : faces) {
    int& s = slot[sets.find(f)];
    if (s < 0) s = static_cast<int>(out.size()), out.emplace_back();
    out[s].push_back(f);
  }
  return out;
}

[[noreturn]] void refuse(const Mesh& mesh, const std::vector<int>& piece, int index, int count,
                         const std::string& problem) {
  std::vector<int> file;
  for (int f : piece) file.push_back(mesh.file_face[f]);
  const std::string which =
      count > 1 ? "contact surface component " + std::to_string(index + 1) + " of " + std::to_string(count)
                : "contact surface";
  throw InputError(
      mesh.source,
      which + " (" + std::to_string(piece.size()) + " faces: file faces " + first_few(file) + ")", problem,
      "a curved contact surface is flattened piece by piece and each piece must be a topological disk: "
      "select a disk-shaped region, or split a closed or ring-shaped surface with a cut");
}

/// Checks that `piece` is a triangulated topological disk (manifold, consistently
/// oriented, one border, V - E + F = 1) and builds it as a Surface_mesh.
void disk_surface_mesh(const Mesh& mesh, const std::vector<int>& piece, int index, int count, SurfaceMesh& sm,
                       std::vector<int>& mesh_vertex_of) {
  for (int f : piece)
    if (detail::has_repeated_vertex(mesh.faces[f]))
      refuse(mesh, piece, index, count,
             "has a face with a repeated vertex (run repair, which drops degenerate faces)");
  const detail::EdgeTable edges = detail::build_edge_table(mesh, piece);
  for (int e = 0; e < edges.edge_count(); ++e) {
    if (edges.use_count(e) > 2)
      refuse(mesh, piece, index, count, "has an edge shared by more than two faces");
    if (edges.use_count(e) == 2 && edges.use(e, 0).forward == edges.use(e, 1).forward)
      refuse(mesh, piece, index, count, "is not consistently oriented (run repair)");
  }
  if (!detail::to_surface_mesh(mesh, piece, sm, &mesh_vertex_of))
    refuse(mesh, piece, index, count, "is not a manifold surface");
  int borders = 0;
  std::vector<char> seen(sm.number_of_halfedges(), 0);
  for (auto h : sm.halfedges()) {
    if (!sm.is_border(h) || seen[h.idx()]) continue;
    ++borders;
    for (auto g = h; !seen[g.idx()]; g = sm.next(g)) seen[g.idx()] = 1;
  }
  for (auto v : sm.vertices())  // a vertex with two border fans (pinched disk)
    if (sm.is_border(v)) {
      int border_out = 0;
      for (auto h : CGAL::halfedges_around_source(v, sm)) border_out += sm.is_border(h);
      if (border_out > 1) refuse(mesh, piece, index, count, "has a vertex where the surface touches itself");
    }
  const long euler = static_cast<long>(sm.number_of_vertices()) - static_cast<long>(sm.number_of_edges()) +
                     static_cast<long>(sm.number_of_faces());
  if (borders != 1 || euler != 1)
    refuse(mesh, piece, index, count,
           "is not a topological disk: it has " + std::to_string(borders) +
               (borders == 1 ? " border" : " borders") +
               " and Euler characteristic V - E + F = " + std::to_string(euler) + " (a disk has 1 and 1)");
}

/// Charts one disk-shaped piece with LSCM or ARAP; returns per-vertex UVs
/// (mesh vertex -> uv) scaled to the piece's 3D area, its main 2D axis along u.
std::vector<std::pair<int, Vec2>> flatten(const Mesh& mesh, const std::vector<int>& piece, int index,
                                          int count, ChartMethod method) {
  SurfaceMesh sm;
  std::vector<int> mesh_vertex_of;
  disk_surface_mesh(mesh, piece, index, count, sm, mesh_vertex_of);
  auto uvmap = sm.add_property_map<SurfaceMesh::Vertex_index, detail::Kernel::Point_2>("v:uv").first;
  SurfaceMesh::Halfedge_index border;
  for (auto h : sm.halfedges())
    if (sm.is_border(h)) {
      border = h;
      break;
    }
  const SMP::Error_code status =
      method == ChartMethod::arap
          ? SMP::parameterize(sm, SMP::ARAP_parameterizer_3<SurfaceMesh>(), border, uvmap)
          : SMP::parameterize(sm, SMP::LSCM_parameterizer_3<SurfaceMesh>(), border, uvmap);
  if (status != SMP::OK)
    refuse(mesh, piece, index, count,
           std::string("could not be flattened: CGAL says ") + SMP::get_error_message(status));

  const int n = static_cast<int>(mesh_vertex_of.size());
  std::vector<Vec2> uv(n);
  for (auto v : sm.vertices()) uv[v.idx()] = Vec2(uvmap[v].x(), uvmap[v].y());
  std::vector<int> local(mesh.vertices.size(), -1);
  for (int i = 0; i < n; ++i) local[mesh_vertex_of[i]] = i;
  double area2 = 0, area3 = 0;
  for (int f : piece) {
    const auto& c = mesh.faces[f];
    area2 += signed_area(uv[local[c[0]]], uv[local[c[1]]], uv[local[c[2]]]);
    area3 += mesh.face_area(f);
  }
  if (!(std::abs(area2) > 0) || !std::isfinite(area2))
    refuse(mesh, piece, index, count, "could not be flattened: the chart has no area");
  // Mirror if needed (faces counter-clockwise seen from outside stay
  // counter-clockwise), scale to the 3D area, centre.
  const double scale = std::sqrt(area3 / std::abs(area2));
  Vec2 mean = Vec2::Zero();
  for (auto& p : uv) {
    if (area2 < 0) p.y() = -p.y();
    p *= scale;
    mean += p;
  }
  mean /= n;
  // Rotate the main 2D axis onto u; its sign: the 3D direction it maps to
  // (least-squares fit of positions against uv) has a positive largest component.
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (auto& p : uv) {
    p -= mean;
    cov += p * p.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
  Vec2 a = eig.eigenvectors().col(1);
  Eigen::MatrixXd A(n, 3), P(n, 3);
  for (int i = 0; i < n; ++i) {
    A.row(i) << uv[i].x(), uv[i].y(), 1.0;
    P.row(i) = mesh.vertices[mesh_vertex_of[i]].transpose();
  }
  const Eigen::MatrixXd J = A.colPivHouseholderQr().solve(P);  // rows: d/du, d/dv, offset
  const Vec3 along = J.row(0).transpose() * a.x() + J.row(1).transpose() * a.y();
  if (canonical_sign(along).dot(along) < 0) a = -a;
  const Vec2 b(-a.y(), a.x());
  std::vector<std::pair<int, Vec2>> out;
  out.reserve(n);
  for (int i = 0; i < n; ++i) out.push_back({mesh_vertex_of[i], Vec2(uv[i].dot(a), uv[i].dot(b))});
  return out;
}

/// Interior angles of a triangle (radians).
std::array<double, 3> angles(const std::array<Vec3, 3>& p) {
  std::array<double, 3> a{};
  for (int k = 0; k < 3; ++k) {
    const Vec3 u = p[(k + 1) % 3] - p[k], v = p[(k + 2) % 3] - p[k];
    a[k] = std::atan2(u.cross(v).norm(), u.dot(v));
  }
  return a;
}

/// Area ratio and angle error per face, uv bounds.
void measure(const Mesh& mesh, Chart& chart) {
  chart.area_ratio_min = std::numeric_limits<double>::infinity();
  chart.area_ratio_max = -chart.area_ratio_min;
  chart.angle_error_mean_deg = chart.angle_error_max_deg = 0;
  const auto [lo, hi] = bounding_box(mesh);
  const double tiny = 1e-14 * (hi - lo).squaredNorm();
  int measured = 0, flipped = 0;
  for (int f : chart.faces) {
    const double a3 = mesh.face_area(f);
    if (a3 <= tiny) continue;
    const auto& c = mesh.faces[f];
    const Vec2 &p = chart.uv[c[0]], &q = chart.uv[c[1]], &r = chart.uv[c[2]];
    const double ratio = signed_area(p, q, r) / a3;
    flipped += ratio <= 0;
    chart.area_ratio_min = std::min(chart.area_ratio_min, ratio);
    chart.area_ratio_max = std::max(chart.area_ratio_max, ratio);
    const auto a = angles({mesh.corner(f, 0), mesh.corner(f, 1), mesh.corner(f, 2)});
    const auto b = angles({Vec3(p.x(), p.y(), 0), Vec3(q.x(), q.y(), 0), Vec3(r.x(), r.y(), 0)});
    double worst = 0;
    for (int k = 0; k < 3; ++k) worst = std::max(worst, std::abs(a[k] - b[k]) * 180 / std::numbers::pi);
    chart.angle_error_mean_deg += worst;
    chart.angle_error_max_deg = std::max(chart.angle_error_max_deg, worst);
    ++measured;
  }
  if (measured)
    chart.angle_error_mean_deg /= measured;
  else
    chart.area_ratio_min = chart.area_ratio_max = 1;
  chart.uv_min = Vec2::Constant(std::numeric_limits<double>::infinity());
  chart.uv_max = -chart.uv_min;
  for (const Vec2& p : chart.uv)
    if (!std::isnan(p.x())) chart.uv_min = chart.uv_min.cwiseMin(p), chart.uv_max = chart.uv_max.cwiseMax(p);
  if (flipped)
    chart.notes.push_back(std::to_string(flipped) +
                          " faces are folded over in the chart (they overlap other faces)");
  chart.notes.push_back("distortion: area ratio (2D/3D) " + significant_digits(chart.area_ratio_min, 3) +
                        " to " + significant_digits(chart.area_ratio_max, 3) + ", angle error mean " +
                        significant_digits(chart.angle_error_mean_deg, 3) + "°, max " +
                        significant_digits(chart.angle_error_max_deg, 3) + "°");
}

}  // namespace

std::string_view to_string(ChartMethod method) {
  switch (method) {
    case ChartMethod::automatic:
      return "automatic";
    case ChartMethod::planar:
      return "planar";
    case ChartMethod::lscm:
      return "lscm";
    case ChartMethod::arap:
      return "arap";
  }
  return "?";
}

void ChartOptions::validate() const {
  if (!(planar_tolerance_mm >= 0 && std::isfinite(planar_tolerance_mm)))
    throw std::invalid_argument("ChartOptions: planar_tolerance_mm = " + std::to_string(planar_tolerance_mm) +
                                " must be finite and >= 0");
  if (!(component_gap_mm >= 0 && std::isfinite(component_gap_mm)))
    throw std::invalid_argument("ChartOptions: component_gap_mm = " + std::to_string(component_gap_mm) +
                                " must be finite and >= 0");
}

Chart compute_chart(const Mesh& mesh, const ContactSurface& contact, const ChartOptions& options) {
  options.validate();
  mesh.check_consistent();
  if (contact.is_contact.size() != mesh.faces.size())
    throw std::invalid_argument("compute_chart: contact surface has " +
                                std::to_string(contact.is_contact.size()) + " face flags for a mesh of " +
                                std::to_string(mesh.faces.size()) + " faces");
  for (int f : contact.faces)
    if (f < 0 || f >= mesh.num_faces() || !contact.is_contact[f])
      throw std::invalid_argument("compute_chart: contact face " + std::to_string(f) +
                                  " is out of range or unflagged");
  if (contact.faces.empty())
    throw InputError(mesh.source, "contact surface", "has no faces, so there is nothing to chart",
                     "select the faces that touch the skin");

  Chart chart;
  chart.faces = contact.faces;
  chart.uv.assign(mesh.vertices.size(), Vec2::Constant(std::numeric_limits<double>::quiet_NaN()));
  const std::vector<int> verts = used_vertices(mesh, chart.faces);
  const auto pieces = components(mesh, chart.faces, detail::build_edge_table(mesh, chart.faces));
  chart.components = static_cast<int>(pieces.size());
  const Plane plane = fit_plane(mesh, chart.faces, verts);
  const bool flat = plane.max_distance <= options.planar_tolerance_mm;

  if (options.method == ChartMethod::planar && !flat)
    throw InputError(mesh.source, "contact surface",
                     "is not flat: a vertex lies " + significant_digits(plane.max_distance, 3) +
                         " mm from the best-fit plane, more than planar_tolerance_mm = " +
                         significant_digits(options.planar_tolerance_mm, 3),
                     "use the lscm or arap chart, or raise the tolerance");
  if (flat && (options.method == ChartMethod::planar || options.method == ChartMethod::automatic)) {
    Chart planar = chart;
    planar.method = ChartMethod::planar;
    planar.axis_u = plane.axis_u;
    planar.axis_v = plane.axis_v;
    Vec2 lo = Vec2::Constant(std::numeric_limits<double>::infinity());
    for (int v : verts) {
      const Vec3 d = mesh.vertices[v] - plane.centre;
      planar.uv[v] = Vec2(d.dot(plane.axis_u), d.dot(plane.axis_v));
      lo = lo.cwiseMin(planar.uv[v]);
    }
    for (int v : verts) planar.uv[v] -= lo;  // chart starts at (0, 0)
    planar.origin = plane.centre + lo.x() * plane.axis_u + lo.y() * plane.axis_v;
    planar.notes.push_back("planar projection: the contact vertices lie within " +
                           significant_digits(plane.max_distance, 3) + " mm of their plane");
    measure(mesh, planar);
    if (planar.area_ratio_min > 0) return planar;
    if (options.method == ChartMethod::planar)
      throw InputError(
          mesh.source, "contact surface",
          "is flat but folds over itself (faces on both sides of the plane overlap in projection)",
          "select only the faces of one side");
    chart.notes.push_back("the flat contact surface folds over itself; using lscm instead of a projection");
  }

  chart.method = options.method == ChartMethod::arap ? ChartMethod::arap : ChartMethod::lscm;
  std::vector<int> owner(mesh.vertices.size(), -1);  // a vertex has one chart position
  for (int i = 0; i < chart.components; ++i)
    for (int v : used_vertices(mesh, pieces[i])) {
      if (owner[v] >= 0)
        refuse(mesh, pieces[i], i, chart.components,
               "touches component " + std::to_string(owner[v] + 1) + " at vertex " + std::to_string(v) +
                   ", which cannot sit in two places of the chart");
      owner[v] = i;
    }
  double offset = 0;
  for (int i = 0; i < static_cast<int>(pieces.size()); ++i) {
    auto uv = flatten(mesh, pieces[i], i, static_cast<int>(pieces.size()), chart.method);
    Vec2 lo = Vec2::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (const auto& [v, p] : uv) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    for (const auto& [v, p] : uv) chart.uv[v] = p - lo + Vec2(offset, 0);
    offset += hi.x() - lo.x() + options.component_gap_mm;
  }
  chart.notes.push_back(
      std::string(to_string(chart.method)) + " chart scaled so each piece keeps its 3D area" +
      (pieces.size() > 1 ? "; " + std::to_string(pieces.size()) + " pieces laid side by side, " +
                               significant_digits(options.component_gap_mm, 3) + " mm apart"
                         : ""));
  measure(mesh, chart);
  return chart;
}

}  // namespace clearfit
