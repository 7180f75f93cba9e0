#include <algorithm>
#include <clearfit/fit/hotspots.hpp>
#include <cmath>
#include <limits>
#include <map>
#include <opencv2/imgproc.hpp>
#include <set>
#include <stdexcept>

namespace clearfit {

ChartRaster rasterize_chart(const Mesh& mesh, const Chart& chart, const ChartGrid& grid) {
  ChartRaster r;
  r.grid = grid;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  r.face.assign(grid.size(), -1);
  r.point.assign(grid.size(), Vec3::Constant(nan));
  r.area_mm2.assign(grid.size(), 0.f);
  const double texel_area = grid.texel_mm * grid.texel_mm;
  for (int f : chart.faces) {
    const auto& tri = mesh.faces[f];
    const Vec2 a = chart.uv[tri[0]], b = chart.uv[tri[1]], c = chart.uv[tri[2]];
    if (!(a.allFinite() && b.allFinite() && c.allFinite())) continue;
    const double area2 = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    if (std::abs(area2) < 1e-18) continue;
    const Vec3 &A = mesh.vertices[tri[0]], &B = mesh.vertices[tri[1]], &C = mesh.vertices[tri[2]];
    const double ratio = (B - A).cross(C - A).norm() / std::abs(area2);
    const Vec2 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
    const int i0 = std::max(0, static_cast<int>(std::ceil((lo.x() - grid.uv_origin.x()) / grid.texel_mm)));
    const int i1 = std::min(grid.width - 1, static_cast<int>(std::floor((hi.x() - grid.uv_origin.x()) / grid.texel_mm)));
    const int j0 = std::max(0, static_cast<int>(std::ceil((lo.y() - grid.uv_origin.y()) / grid.texel_mm)));
    const int j1 = std::min(grid.height - 1, static_cast<int>(std::floor((hi.y() - grid.uv_origin.y()) / grid.texel_mm)));
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const Vec2 p = grid.uv(i, j);
        // Barycentrics of p; half-open on edges so a texel on a shared edge goes to one face.
        const double w1 = ((p - a).x() * (c - a).y() - (p - a).y() * (c - a).x()) / area2;
        const double w2 = ((b - a).x() * (p - a).y() - (b - a).y() * (p - a).x()) / area2;
        const double w0 = 1 - w1 - w2;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const auto k = grid.index(i, j);
        if (r.face[k] >= 0) continue;
        r.face[k] = f;
        r.point[k] = w0 * A + w1 * B + w2 * C;
        r.area_mm2[k] = static_cast<float>(texel_area * ratio);
      }
  }
  return r;
}

std::vector<Hotspot> find_hotspots(const ChartField& field, const ChartField* sigma, const std::vector<std::uint8_t>* flags,
                                   const ChartRaster& raster, const HotspotOptions& options,
                                   std::vector<std::vector<int>>* labels) {
  const ChartGrid& g = field.grid;
  if (raster.grid.width != g.width || raster.grid.height != g.height)
    throw std::invalid_argument("find_hotspots: the raster's grid differs from the field's");
  if (sigma && sigma->value.size() != g.size()) throw std::invalid_argument("find_hotspots: sigma has another size");
  if (flags && flags->size() != g.size()) throw std::invalid_argument("find_hotspots: flags have another size");
  std::vector<Hotspot> all;
  if (labels) labels->clear();
  for (double threshold : options.thresholds) {
    cv::Mat mask(g.height, g.width, CV_8U);
    for (int j = 0; j < g.height; ++j)
      for (int i = 0; i < g.width; ++i) {
        const float v = field.value[g.index(i, j)];
        mask.at<std::uint8_t>(j, i) = std::isfinite(v) && v >= threshold ? 1 : 0;
      }
    cv::Mat lab;
    const int n = cv::connectedComponents(mask, lab, 8, CV_32S);
    struct Acc {
      double area = 0, sum = 0, sum_w = 0, sum_vf = 0, peak = -1e300, peak_sigma = 0, sigma_sum = 0;
      Vec3 c = Vec3::Zero(), cp = Vec3::Zero();
      Vec2 uv = Vec2::Zero();
      std::set<int> faces;
      long long texels = 0, flagged = 0;
    };
    std::vector<Acc> acc(n);
    for (int j = 0; j < g.height; ++j)
      for (int i = 0; i < g.width; ++i) {
        const int l = lab.at<int>(j, i);
        if (l == 0) continue;
        const auto k = g.index(i, j);
        Acc& a = acc[l];
        const double v = field.value[k];
        const double area = raster.face[k] >= 0 ? raster.area_mm2[k] : g.texel_mm * g.texel_mm;
        a.area += area;
        a.sum += v * area;
        a.texels += 1;
        if (raster.face[k] >= 0) {
          a.c += area * raster.point[k];
          a.cp += v * area * raster.point[k];
          a.sum_w += area;
          a.sum_vf += v * area;
          a.faces.insert(raster.face[k]);
        }
        a.uv += area * g.uv(i, j);
        const double s = sigma ? sigma->value[k] : std::numeric_limits<double>::quiet_NaN();
        a.sigma_sum += s * area;
        if (v > a.peak) a.peak = v, a.peak_sigma = s;
        if (flags && (*flags)[k]) ++a.flagged;
      }
    std::vector<int> relabel(n, 0);
    std::vector<Hotspot> found;
    for (int l = 1; l < n; ++l) {
      const Acc& a = acc[l];
      if (a.area < options.min_area_mm2) continue;
      Hotspot h;
      h.threshold = threshold;
      h.peak = a.peak;
      h.peak_sigma = a.peak_sigma;
      h.mean = a.sum / a.area;
      // Mean of correlated texels: σ̄ / sqrt(independent samples in the region).
      h.mean_sigma = (a.sigma_sum / a.area) / std::sqrt(std::max(1.0, a.area * options.samples_per_mm2));
      h.area_mm2 = a.area;
      h.centroid_uv_mm = a.uv / a.area;
      if (a.sum_w > 0) {
        h.centroid_mm = a.c / a.sum_w;
        h.centre_of_pressure_mm = std::abs(a.sum_vf) > 0 ? Vec3(a.cp / a.sum_vf) : h.centroid_mm;
      } else {
        h.centroid_mm = h.centre_of_pressure_mm = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
      }
      h.faces.assign(a.faces.begin(), a.faces.end());
      h.texels = a.texels;
      h.flagged_texels = a.flagged;
      h.id = l;  // provisional: the component label
      found.push_back(std::move(h));
    }
    std::sort(found.begin(), found.end(), [](const Hotspot& x, const Hotspot& y) { return x.peak > y.peak; });
    for (auto& h : found) {
      const int component = h.id;
      h.id = static_cast<int>(all.size()) + 1;
      relabel[component] = h.id;
      all.push_back(h);
    }
    if (labels) {
      std::vector<int> image(g.size(), 0);
      for (int j = 0; j < g.height; ++j)
        for (int i = 0; i < g.width; ++i) image[g.index(i, j)] = relabel[lab.at<int>(j, i)];
      labels->push_back(std::move(image));
    }
  }
  return all;
}

}  // namespace clearfit
