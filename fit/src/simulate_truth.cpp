// Pressure fields on the contact chart, the ground truth written beside
// synthetic captures, and small .npy helpers.
#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/fit/contact_mechanics.hpp>
#include <clearfit/fit/hotspots.hpp>
#include <clearfit/fit/simulate.hpp>
#include <clearfit/npy.hpp>

#include <opencv2/imgproc.hpp>

#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

namespace clearfit::sim {

namespace {
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// Barycentric weights of p in the 2D triangle (a, b, c); nullopt when degenerate.
std::optional<Eigen::Vector3d> barycentric2(const Vec2& p, const Vec2& a, const Vec2& b, const Vec2& c) {
  const Vec2 v0 = b - a, v1 = c - a, v2 = p - a;
  const double den = v0.x() * v1.y() - v1.x() * v0.y();
  if (!(std::abs(den) > 1e-300)) return std::nullopt;
  const double w1 = (v2.x() * v1.y() - v1.x() * v2.y()) / den, w2 = (v0.x() * v2.y() - v2.x() * v0.y()) / den;
  return Eigen::Vector3d(1 - w1 - w2, w1, w2);
}

}  // namespace

double PressureSource::pressure_kpa(double r) const {
  switch (kind) {
    case Kind::gaussian: return peak_kpa * std::exp(-r * r / (2 * sigma_mm * sigma_mm));
    case Kind::punch: return contact::FlatPunch{radius_mm, force_n, rim_cap_ratio}.pressure_kpa(r);
    case Kind::hertz: return contact::HertzSphere{sphere_radius_mm, force_n, e_star_kpa}.pressure_kpa(r);
  }
  return 0;
}

std::string PressureSource::kind_name() const {
  return kind == Kind::gaussian ? "gaussian" : kind == Kind::punch ? "punch" : "hertz";
}

SurfacePoint nearest_contact_point(const Mesh& mesh, const ContactSurface& contact, const Chart& chart, const Vec3& q) {
  SurfacePoint best;
  best.distance_mm = std::numeric_limits<double>::infinity();
  for (int f : contact.faces) {
    const auto& v = mesh.faces[f];
    const Eigen::Vector3d w = closest_barycentric(q, mesh.vertices[v[0]], mesh.vertices[v[1]], mesh.vertices[v[2]]);
    const Vec3 p = w[0] * mesh.vertices[v[0]] + w[1] * mesh.vertices[v[1]] + w[2] * mesh.vertices[v[2]];
    const double d = (p - q).norm();
    if (d < best.distance_mm) {
      const Vec2 uv = w[0] * chart.uv[v[0]] + w[1] * chart.uv[v[1]] + w[2] * chart.uv[v[2]];
      if (!uv.allFinite()) continue;
      best = {p, uv, d, f};
    }
  }
  return best;
}

std::optional<Vec3> part_point_at_uv(const Mesh& mesh, const Chart& chart, const Vec2& uv) {
  std::optional<Vec3> best;
  double best_out = 1e-9;  // tolerance: how far outside a face (in barycentric units) still counts
  for (int f : chart.faces) {
    const auto& v = mesh.faces[f];
    const auto w = barycentric2(uv, chart.uv[v[0]], chart.uv[v[1]], chart.uv[v[2]]);
    if (!w) continue;
    const double out = -std::min(0.0, w->minCoeff());
    if (out <= best_out) {
      best_out = out;
      best = (*w)[0] * mesh.vertices[v[0]] + (*w)[1] * mesh.vertices[v[1]] + (*w)[2] * mesh.vertices[v[2]];
      if (out == 0) break;
    }
  }
  return best;
}

PressureTruth make_pressure_truth(const Mesh& mesh, const ContactSurface& contact, const Chart& chart,
                                  const PressureFieldSpec& spec) {
  if (chart.uv.size() != mesh.vertices.size() || chart.faces.empty())
    throw std::invalid_argument("make_pressure_truth: the chart does not belong to the mesh or is empty");
  PressureTruth t;
  const ChartGrid g = ChartGrid::covering(chart.uv_min, chart.uv_max, spec.texel_mm);
  // Texels whose centre lies on a charted contact face.
  const ChartRaster raster = rasterize_chart(mesh, chart, g);
  std::vector<char> inside(g.size(), 0);
  for (std::size_t k = 0; k < g.size(); ++k) inside[k] = raster.face[k] >= 0;
  std::vector<std::optional<SurfaceLoad>> loads;  // part-frame sources, on the 3D surface
  for (const PressureSource& s : spec.sources) {
    loads.emplace_back();
    if (s.center_uv_mm) {
      t.source_uv_mm.push_back(*s.center_uv_mm);
      t.source_part_mm.push_back(part_point_at_uv(mesh, chart, *s.center_uv_mm));
    } else if (s.center_part_mm) {
      const SurfacePoint sp = nearest_contact_point(mesh, contact, chart, *s.center_part_mm);
      if (!(sp.distance_mm <= 5.0)) {
        std::ostringstream m;
        m << "the centre of pressure source '" << s.name << "' is " << sp.distance_mm << " mm from the contact surface";
        throw InputError("", "source '" + s.name + "'", m.str() + " (at most 5 mm)", "give a point on or near the contact surface, or center_uv_mm");
      }
      t.source_uv_mm.push_back(sp.uv);
      t.source_part_mm.push_back(sp.point);
      loads.back() = SurfaceLoad::at(s, sp, mesh.face_normal(sp.face));
    } else {
      throw std::invalid_argument("make_pressure_truth: source '" + s.name + "' has no centre");
    }
  }
  if (spec.user_map) {
    const ChartGrid& u = spec.user_map->grid;
    if (u.width != g.width || u.height != g.height || std::abs(u.texel_mm - g.texel_mm) > 1e-9 ||
        (u.uv_origin - g.uv_origin).norm() > 1e-6) {
      std::ostringstream m;
      m << "the pressure map is " << u.width << " x " << u.height << " texels; the chart grid is " << g.width << " x "
        << g.height << " texels of " << g.texel_mm << " mm from uv (" << g.uv_origin.x() << ", " << g.uv_origin.y() << ")";
      throw InputError("", "pressure map", m.str(), "render the map on that grid (truth_pressure.npy of a run shows it)");
    }
  }
  t.pressure.grid = g;
  t.pressure.value.assign(g.size(), kNaN);
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      if (!inside[g.index(i, j)]) continue;
      const Vec2 uv = g.uv(i, j);
      const std::size_t texel = g.index(i, j);
      const Vec3 face_normal = mesh.face_normal(raster.face[texel]);
      double p = 0;
      for (std::size_t k = 0; k < spec.sources.size(); ++k)
        p += loads[k] ? loads[k]->pressure_kpa(raster.point[texel], face_normal)
                      : spec.sources[k].pressure_kpa((uv - t.source_uv_mm[k]).norm());
      if (spec.user_map) {
        const float u = spec.user_map->value[g.index(i, j)];
        if (std::isfinite(u)) p += u;
      }
      t.pressure.value[g.index(i, j)] = static_cast<float>(p);
    }
  t.vertex_pressure = sample_at_vertices(t.pressure, chart);
  // Hotspots: 8-connected regions >= 4.3 kPa.
  cv::Mat mask(g.height, g.width, CV_8U, cv::Scalar(0));
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const float p = t.pressure.value[g.index(i, j)];
      mask.at<std::uint8_t>(j, i) = std::isfinite(p) && p >= 4.3f ? 255 : 0;
    }
  cv::Mat labels;
  const int n = cv::connectedComponents(mask, labels, 8, CV_32S);
  std::vector<Hotspot> hs(std::max(0, n - 1));
  std::vector<double> wsum(hs.size(), 0);
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const int l = labels.at<int>(j, i);
      if (l <= 0) continue;
      const double area = raster.area_mm2[g.index(i, j)];  // skin area, not chart area
      Hotspot& h = hs[l - 1];
      const double p = t.pressure.value[g.index(i, j)];
      h.peak_kpa = std::max(h.peak_kpa, p);
      h.area_above_4_3_mm2 += area;
      if (p >= 5.5) h.area_above_5_5_mm2 += area;
      h.centroid_uv_mm += p * area * g.uv(i, j);
      wsum[l - 1] += p * area;
    }
  for (std::size_t k = 0; k < hs.size(); ++k) {
    hs[k].centroid_uv_mm /= wsum[k];
    hs[k].centroid_part_mm = part_point_at_uv(mesh, chart, hs[k].centroid_uv_mm);
  }
  std::sort(hs.begin(), hs.end(), [](const Hotspot& a, const Hotspot& b) { return a.peak_kpa > b.peak_kpa; });
  t.hotspots = std::move(hs);
  return t;
}

void write_npy_float32(const std::filesystem::path& path, const std::vector<std::size_t>& shape, const float* data) {
  std::size_t row = 1;
  for (std::size_t k = 1; k < shape.size(); ++k) row *= shape[k];
  npy::write_float32(path, shape, [&](std::size_t r, float* out) { std::copy_n(data + r * row, row, out); });
}

cv::Mat read_npy_2d(const std::filesystem::path& path) {
  const npy::Float32Array a = npy::read_float32(path);
  if (a.shape.size() != 2 || a.shape[0] == 0 || a.shape[1] == 0)
    throw InputError(path.string(), "shape", "expected a 2-D array (height, width) of kPa", "");
  cv::Mat m(static_cast<int>(a.shape[0]), static_cast<int>(a.shape[1]), CV_32F);
  std::copy(a.values.begin(), a.values.end(), m.ptr<float>());
  return m;
}

}  // namespace clearfit::sim
