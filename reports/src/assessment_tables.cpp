// Tables people paste: hotspots.csv, vertices.csv and heatmap.ply (the part
// with its per-vertex values as scalar properties) beside heatmap.glb.
#include <clearfit/atomic_file.hpp>
#include <clearfit/format.hpp>
#include <clearfit/reports/assessment_tables.hpp>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <sstream>

namespace clearfit {
namespace {

std::string threshold_name(double t, bool calibrated) {
  std::ostringstream s;
  s << t;
  return calibrated ? s.str() + "_kpa" : s.str();
}

}  // namespace

std::vector<std::uint8_t> vertex_seen(const Assessment& a, const Chart& chart) {
  std::vector<std::uint8_t> seen(chart.uv.size(), 0);
  for (std::size_t v = 0; v < seen.size() && v < a.vertex_signal.size(); ++v)
    seen[v] = chart.uv[v].allFinite() && std::isfinite(a.vertex_signal[v]);
  return seen;
}

void write_hotspots_csv(const Assessment& a, const std::filesystem::path& path) {
  const std::string unit = a.calibrated ? "_kpa" : "_signal";
  const int digits = a.calibrated ? 2 : 5;
  std::ostringstream s;
  s << "id,peak" << unit << ",peak_sigma" << unit << ",mean" << unit << ",mean_sigma" << unit << ",area_mm2,half_peak_area_mm2";
  for (double t : a.thresholds) s << ",area_ge_" << threshold_name(t, a.calibrated) << "_mm2,area_sigma_ge_" << threshold_name(t, a.calibrated) << "_mm2";
  s << ",centroid_x_mm,centroid_y_mm,centroid_z_mm,centre_of_pressure_x_mm,centre_of_pressure_y_mm,centre_of_pressure_z_mm"
       ",centre_of_pressure_sigma_mm,centroid_sigma_mm,unseen_area_mm2,unseen_share,texels,saturated_texels,touches_glare\n";
  for (const Hotspot& h : a.hotspots) {
    s << h.id << ',' << fixed_digits(h.peak, digits, "") << ',' << fixed_digits(h.peak_sigma, digits, "")
      << ',' << fixed_digits(h.mean, digits, "") << ',' << fixed_digits(h.mean_sigma, digits, "") << ','
      << fixed_digits(h.area_mm2, 4, "") << ',' << fixed_digits(h.half_peak_area_mm2, 4, "");
    for (double t : a.thresholds) {
      const HotspotLevel* level = nullptr;
      for (const HotspotLevel& l : h.levels)
        if (l.threshold == t) level = &l;
      s << ',' << (level ? fixed_digits(level->area_mm2, 4, "") : "") << ','
        << (level ? fixed_digits(level->area_sigma_mm2, 4, "") : "");
    }
    for (const Vec3* p : {&h.centroid_mm, &h.centre_of_pressure_mm})
      for (int c = 0; c < 3; ++c) s << ',' << fixed_digits((*p)[c], 4, "");
    s << ',' << fixed_digits(h.centre_of_pressure_sigma_mm, 4, "") << ',' << fixed_digits(h.centroid_sigma_mm, 4, "");
    const double both = h.area_mm2 + h.unseen_area_mm2;
    s << ',' << fixed_digits(h.unseen_area_mm2, 4, "") << ','
      << fixed_digits(both > 0 ? h.unseen_area_mm2 / both : 0.0, 4, "") << ',' << h.texels << ','
      << h.flagged_texels << ',' << (h.touches_mask ? 1 : 0) << '\n';
  }
  write_file_atomically(path, s.str());
}

void write_vertex_csv(const Assessment& a, const Mesh& mesh, const Chart& chart, const std::filesystem::path& path) {
  const std::vector<std::uint8_t> seen = vertex_seen(a, chart);
  write_file_atomically(path, [&](std::ostream& out) {
    out << "vertex,x_mm,y_mm,z_mm,contact,seen,pressure_kpa,signal,pressure_sigma_kpa\n";
    for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
      const Vec3& p = mesh.vertices[v];
      const bool contact = v < chart.uv.size() && chart.uv[v].allFinite();
      const bool s = v < seen.size() && seen[v];
      out << v << ',' << fixed_digits(p.x(), 5, "") << ',' << fixed_digits(p.y(), 5, "") << ','
          << fixed_digits(p.z(), 5, "") << ',' << (contact ? 1 : 0) << ',' << (s ? 1 : 0) << ','
          << (s && a.calibrated ? fixed_digits(a.vertex_pressure[v], 3, "") : "") << ','
          << (s ? fixed_digits(a.vertex_signal[v], 6, "") : "") << ','
          << (s && a.calibrated && v < a.vertex_pressure_sigma.size()
                  ? fixed_digits(a.vertex_pressure_sigma[v], 3, "")
                  : "")
          << '\n';
    }
  });
}

void write_vertex_ply(const Assessment& a, const Mesh& mesh, const Chart& chart, const std::filesystem::path& path) {
  const std::vector<std::uint8_t> seen = vertex_seen(a, chart);
  write_file_atomically(path, [&](std::ostream& out) {
    out << "ply\nformat binary_little_endian 1.0\ncomment clearfit assessment: per-vertex values (part frame, mm); "
           "pressure_kpa and signal are 0 where seen is 0 (off the contact surface or not seen)\n"
        << "element vertex " << mesh.vertices.size()
        << "\nproperty float x\nproperty float y\nproperty float z\nproperty float pressure_kpa\nproperty float signal\n"
           "property uchar seen\n"
        << "element face " << mesh.faces.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
    auto put = [&](const void* data, std::size_t n) { out.write(static_cast<const char*>(data), static_cast<std::streamsize>(n)); };
    static_assert(std::endian::native == std::endian::little, "the PLY is written little-endian");
    for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
      const bool s = v < seen.size() && seen[v];
      const float values[5] = {static_cast<float>(mesh.vertices[v].x()), static_cast<float>(mesh.vertices[v].y()),
                               static_cast<float>(mesh.vertices[v].z()), s && a.calibrated ? a.vertex_pressure[v] : 0.f,
                               s ? a.vertex_signal[v] : 0.f};
      put(values, sizeof values);
      const std::uint8_t flag = s ? 1 : 0;
      put(&flag, 1);
    }
    for (const auto& f : mesh.faces) {
      const std::uint8_t three = 3;
      const std::int32_t idx[3] = {static_cast<std::int32_t>(f[0]), static_cast<std::int32_t>(f[1]), static_cast<std::int32_t>(f[2])};
      put(&three, 1);
      put(idx, sizeof idx);
    }
  });
}

}  // namespace clearfit
