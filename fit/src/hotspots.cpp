#include <algorithm>
#include <clearfit/fit/hotspots.hpp>
#include <cmath>
#include <limits>
#include <map>
#include <opencv2/imgproc.hpp>
#include <set>
#include <stdexcept>
#include <utility>

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

Eigen::Vector3d closest_barycentric(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {1 - v, v, 0};
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {1 - w, 0, w};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - w, w};
  }
  const double denom = 1 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return {1 - v - w, v, w};
}

/// |∇v| at texel (i, j) per mm: central differences, one-sided beside undefined texels; 0 when neither side is.
double gradient_norm(const ChartField& f, int i, int j) { return gradient(f, i, j).norm(); }

Eigen::Vector2d gradient(const ChartField& f, int i, int j) {
  const ChartGrid& g = f.grid;
  auto along = [&](int di, int dj) {
    auto at = [&](int x, int y) { return x >= 0 && y >= 0 && x < g.width && y < g.height ? f.value[g.index(x, y)] : NAN; };
    const float here = at(i, j), hi = at(i + di, j + dj), lo = at(i - di, j - dj);
    const bool ahead = std::isfinite(hi), back = std::isfinite(lo);
    const int steps = ahead + back;
    return steps ? ((ahead ? hi : here) - (back ? lo : here)) / (steps * g.texel_mm) : 0.0;
  };
  return Eigen::Vector2d(along(1, 0), along(0, 1));
}

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Components (8-connected) of the seen texels at or above `threshold` within
/// their σ (value + σ ≥ threshold, so the lowest level's σ band belongs to its
/// place), joined by the unseen contact texels within `reach` texels of them.
cv::Mat place_components(const ChartField& field, const ChartField* sigma, const ChartRaster& raster, double threshold,
                         double reach_texels, int* count) {
  const ChartGrid& g = field.grid;
  cv::Mat above(g.height, g.width, CV_8U, cv::Scalar(0)), unseen(g.height, g.width, CV_8U, cv::Scalar(0));
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const float v = field.value[g.index(i, j)];
      const float s = sigma ? sigma->value[g.index(i, j)] : 0.f;
      above.at<std::uint8_t>(j, i) = std::isfinite(v) && v + (std::isfinite(s) ? s : 0.f) >= threshold;
      unseen.at<std::uint8_t>(j, i) = !std::isfinite(v) && raster.face[g.index(i, j)] >= 0;
    }
  cv::Mat mask = above.clone();
  if (reach_texels > 0 && cv::countNonZero(unseen) > 0 && cv::countNonZero(above) > 0) {
    cv::Mat distance;
    cv::distanceTransform(1 - above, distance, cv::DIST_L2, cv::DIST_MASK_PRECISE);
    mask |= unseen & (distance <= reach_texels);
  }
  cv::Mat labels;
  *count = cv::connectedComponents(mask, labels, 8, CV_32S);
  return labels;
}

/// Per texel, the share of its noise's correlation area (a Gaussian ρ of σ = √(1 / (2π samples_per_mm2)), the
/// correlation of white noise after the field's smoothing, whose integral is 1 / samples_per_mm2) that lies on
/// texels weighing in a centre of pressure (in a place, above `outline_at`): the neighbours outside do not move
/// it, so a texel at the outline shares its noise with about half its correlation area.
cv::Mat weighing_share(const ChartField& field, const cv::Mat& labels, double outline_at, double samples_per_mm2) {
  const ChartGrid& g = field.grid;
  cv::Mat weighing(g.height, g.width, CV_32F, cv::Scalar(0)), share;
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i)
      weighing.at<float>(j, i) = labels.at<int>(j, i) > 0 && field.value[g.index(i, j)] > outline_at ? 1.f : 0.f;
  const double sigma_px = std::sqrt(1.0 / (2 * M_PI * samples_per_mm2)) / g.texel_mm;
  cv::GaussianBlur(weighing, share, cv::Size(), sigma_px, sigma_px, cv::BORDER_CONSTANT);
  return share;
}

struct LevelSums {
  // noise_sum, shared_sum, residual_sum: Σ area σ_n, Σ area σ_s and Σ area r over the level; outline_var: Σ over the
  // band |v − t| < σ of area σ_n² ℓ / (2σ|∇v|) (the outline's noise, in mm⁴); outline_shared, outline_residual: Σ over
  // it of area σ_s / (2σ) and area r / (2σ) (mm²).
  double area = 0, sum = 0, noise_sum = 0, shared_sum = 0, residual_sum = 0, outline_var = 0, outline_shared = 0, outline_residual = 0;
  long long texels = 0;
};

/// A texel's σ split into its shared part (at most σ) and the noise's, σ_n = √(σ² − σ_s² − σ_m²), with σ_m the
/// model's part (at most what the shared part leaves).
std::pair<double, double> split_sigma(double s, const HotspotOptions& o, std::size_t k) {
  auto part = [k](const ChartField* f) { return f && std::isfinite(f->value[k]) ? std::abs(static_cast<double>(f->value[k])) : 0.0; };
  const double sh = std::min(part(o.shared_sigma), s), left = s * s - sh * sh, m = std::min(part(o.model_sigma) * part(o.model_sigma), left);
  return {std::sqrt(std::max(0.0, left - m)), sh};
}

/// A level's area, mean and their σ (HotspotLevel) from its sums.
HotspotLevel level_figures(const LevelSums& L, double threshold, bool with_sigma, double samples_per_mm2) {
  HotspotLevel lv;
  lv.threshold = threshold;
  lv.area_mm2 = L.area;
  lv.area_sigma_mm2 =
      with_sigma ? std::sqrt(L.outline_var + L.outline_shared * L.outline_shared + L.outline_residual * L.outline_residual) : 0.0;
  lv.mean = L.area > 0 ? L.sum / L.area : kNaN;
  lv.mean_sigma = kNaN;
  if (L.area > 0) {
    // The noise's mean σ over √(independent samples in the region), the shared σ's mean as it is, the outline's
    // motion with them (texels of value ≈ t join or leave, moving the mean by (mean − t) δA / A), and the model's
    // residual: its mean over the region (the texels read that much off) less the mean's change as its sum over the
    // outline's band moves the outline (a place read low is also read smaller, its lowest texels left out).
    const double noise = (L.noise_sum / L.area) / std::sqrt(std::max(1.0, L.area * samples_per_mm2));
    const double random_outline = with_sigma ? std::sqrt(L.outline_var + L.outline_shared * L.outline_shared) : 0.0;
    const double outline = (lv.mean - threshold) * random_outline / L.area, shared = L.shared_sum / L.area;
    const double residual = L.residual_sum / L.area - (lv.mean - threshold) * L.outline_residual / L.area;
    lv.mean_sigma = std::sqrt(noise * noise + shared * shared + residual * residual + outline * outline);
  }
  lv.texels = L.texels;
  return lv;
}

struct PlaceSums {
  double area = 0, half_peak_area = 0, unseen = 0, sum_w = 0, sum_vf = 0, peak = -1e300, peak_sigma = 0;
  Vec3 c = Vec3::Zero(), cp = Vec3::Zero();
  // The centre of pressure's variance: Σ k (x − c)² with k = w σ² A (A: the area over which the texel's noise is
  // shared), kept as moments Σk, Σk x, Σk |x|².
  double k0 = 0, k2 = 0;
  Vec3 k1 = Vec3::Zero();
  // The centroid's variance likewise (its outline's term alone): moments m0, m1, m2.
  double m0 = 0, m2 = 0;
  Vec3 m1 = Vec3::Zero();
  Vec2 uv = Vec2::Zero();
  std::set<int> faces;
  long long texels = 0, flagged = 0;
  bool seeded = false;  // holds a seed texel (HotspotOptions::seeds), or no seeds were given
  std::vector<LevelSums> levels;
};

/// The point of the contact surface nearest to `q`: over the faces of the place
/// and the face of the texel whose centre is nearest to q (a ring's mean lies
/// off the ring), exactly on the triangles when the mesh is known.
Vec3 onto_surface(const Vec3& q, const std::set<int>& faces, const ChartRaster& raster, const Mesh* mesh) {
  if (!q.allFinite()) return q;
  double best = INFINITY;
  std::size_t nearest = 0;
  for (std::size_t k = 0; k < raster.face.size(); ++k)
    if (raster.face[k] >= 0) {
      const double d = (raster.point[k] - q).squaredNorm();
      if (d < best) best = d, nearest = k;
    }
  if (!std::isfinite(best)) return q;
  if (!mesh) return raster.point[nearest];
  Vec3 out = raster.point[nearest];
  best = INFINITY;
  auto consider = [&](int f) {
    const auto& t = mesh->faces[f];
    const Vec3 &a = mesh->vertices[t[0]], &b = mesh->vertices[t[1]], &c = mesh->vertices[t[2]];
    const Eigen::Vector3d w = closest_barycentric(q, a, b, c);
    const Vec3 p = w[0] * a + w[1] * b + w[2] * c;
    if ((p - q).squaredNorm() < best) best = (p - q).squaredNorm(), out = p;
  };
  consider(raster.face[nearest]);
  for (int f : faces) consider(f);
  return out;
}

}  // namespace

std::vector<Hotspot> find_hotspots(const ChartField& field, const ChartField* sigma, const std::vector<std::uint8_t>* flags,
                                   const ChartRaster& raster, const HotspotOptions& options, std::vector<int>* labels,
                                   const Mesh* mesh) {
  const ChartGrid& g = field.grid;
  if (raster.grid.width != g.width || raster.grid.height != g.height)
    throw std::invalid_argument("find_hotspots: the raster's grid differs from the field's");
  if (sigma && sigma->value.size() != g.size()) throw std::invalid_argument("find_hotspots: sigma has another size");
  if (flags && flags->size() != g.size()) throw std::invalid_argument("find_hotspots: flags have another size");
  if (labels) labels->assign(g.size(), 0);
  std::vector<double> thresholds = options.thresholds;
  std::sort(thresholds.begin(), thresholds.end());
  if (thresholds.empty()) return {};
  // The centre of pressure's weights: the field above the places' outline level.
  const double outline_at = std::isfinite(options.outline_level) ? std::max(thresholds.front(), options.outline_level) : thresholds.front();
  int n = 0;
  const cv::Mat lab = place_components(field, sigma, raster, thresholds.front(), options.unseen_reach_mm / g.texel_mm, &n);
  const cv::Mat shared = weighing_share(field, lab, outline_at, options.samples_per_mm2);
  std::vector<PlaceSums> acc(n);
  for (auto& a : acc) a.levels.resize(thresholds.size());
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const int l = lab.at<int>(j, i);
      if (l == 0) continue;
      const auto k = g.index(i, j);
      PlaceSums& a = acc[l];
      const double v = field.value[k];
      const double area = raster.face[k] >= 0 ? raster.area_mm2[k] : g.texel_mm * g.texel_mm;
      if (!std::isfinite(v)) {
        a.unseen += area;
        continue;
      }
      const double s = sigma ? sigma->value[k] : kNaN;
      const auto [s_noise, s_shared] = std::isfinite(s) ? split_sigma(s, options, k) : std::pair{kNaN, kNaN};
      const double r = options.residual && std::isfinite(options.residual->value[k]) ? options.residual->value[k] : 0.0;
      const double ell = std::sqrt(std::max(area, 1.0 / options.samples_per_mm2));
      double gradient = -1;  // computed once, where a level's outline needs it
      for (std::size_t t = 0; t < thresholds.size(); ++t) {
        LevelSums& L = a.levels[t];
        if (std::isfinite(s) && s > 0 && std::abs(v - thresholds[t]) < s) {
          if (gradient < 0) gradient = gradient_norm(field, i, j);
          // Without a gradient (an isolated texel) the whole band's half counts as shared.
          if (gradient > 0)
            L.outline_var += area * s_noise * s_noise * ell / (2 * s * gradient), L.outline_shared += area * s_shared / (2 * s),
            L.outline_residual += area * r / (2 * s);
          else
            L.outline_shared += 0.5 * area;
        }
        if (v < thresholds[t]) continue;
        L.area += area, L.sum += v * area, L.noise_sum += s_noise * area, L.shared_sum += s_shared * area, L.residual_sum += r * area, ++L.texels;
      }
      if (std::isfinite(s) && s > 0 && std::abs(v - thresholds.front()) < s && raster.face[k] >= 0) {
        // The outline moves with the noise by σ/|∇v| and takes texels of value t with it: over the band
        // |v − t| < σ (a line of density 1/(2σ)) each texel adds to the centroid (weights w) w σ ℓ / (2|∇v|) times
        // (x − c)²/(Σ w)², its noise shared along the outline over ℓ = √(correlation area). Not to the centre of
        // pressure: its weight v − outline_at is 0 there.
        if (gradient < 0) gradient = gradient_norm(field, i, j);
        if (gradient > 0) {
          const double mm = area * s * ell / (2 * gradient);
          a.m0 += mm, a.m1 += mm * raster.point[k], a.m2 += mm * raster.point[k].squaredNorm();
        }
      }
      if (v < thresholds.front()) continue;  // within σ of the outline: in the lowest level's σ only
      if (!options.seeds || (*options.seeds)[k]) a.seeded = true;
      a.area += area;
      a.texels += 1;
      if (raster.face[k] >= 0) {
        a.c += area * raster.point[k];
        const double lift = std::max(0.0, v - outline_at);
        a.cp += lift * area * raster.point[k];
        a.sum_w += area;
        a.sum_vf += lift * area;
        a.faces.insert(raster.face[k]);
        if (std::isfinite(s) && lift > 0) {
          // ∂c/∂v_i = w_i (x_i − c) / Σ w (v − outline_at); neighbours within the correlation area 1/samples_per_mm2 move
          // together, those of them that weigh in it (weighing_share). The noise's share of σ only: the shared and model
          // parts (the calibration's parameters, the deblur's residual) are smooth over a place and hardly move its centre.
          const double kk = area * s_noise * s_noise * std::max<double>(area, shared.at<float>(j, i) / options.samples_per_mm2);
          a.k0 += kk, a.k1 += kk * raster.point[k], a.k2 += kk * raster.point[k].squaredNorm();
        }
      }
      a.uv += area * g.uv(i, j);
      if (v > a.peak) a.peak = v, a.peak_sigma = s;
      if (flags && (*flags)[k]) ++a.flagged;
    }
  // The area at half the place's peak (its full width at half maximum, as an area).
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i) {
      const int l = lab.at<int>(j, i);
      const auto k = g.index(i, j);
      if (l > 0 && std::isfinite(field.value[k]) && field.value[k] >= 0.5 * acc[l].peak)
        acc[l].half_peak_area += raster.face[k] >= 0 ? raster.area_mm2[k] : g.texel_mm * g.texel_mm;
    }
  std::vector<Hotspot> found;
  for (int l = 1; l < n; ++l) {
    const PlaceSums& a = acc[l];
    if (a.area < options.min_area_mm2 || a.area <= 0 || !a.seeded) continue;
    Hotspot h;
    h.id = l;  // provisional: the component label
    h.threshold = thresholds.front();
    h.peak = a.peak;
    h.peak_sigma = a.peak_sigma;
    for (std::size_t t = 0; t < thresholds.size(); ++t) {
      HotspotLevel lv = level_figures(a.levels[t], thresholds[t], sigma != nullptr, options.samples_per_mm2);
      h.levels.push_back(lv);
    }
    h.area_mm2 = h.levels[0].area_mm2;
    h.half_peak_area_mm2 = a.half_peak_area;
    h.mean = h.levels[0].mean;
    h.mean_sigma = h.levels[0].mean_sigma;
    h.centroid_uv_mm = a.uv / a.area;
    h.faces.assign(a.faces.begin(), a.faces.end());
    if (a.sum_w > 0) {
      h.centroid_mean_mm = a.c / a.sum_w;
      h.centroid_mm = onto_surface(h.centroid_mean_mm, a.faces, raster, mesh);
      h.centre_of_pressure_mm = onto_surface(std::abs(a.sum_vf) > 0 ? Vec3(a.cp / a.sum_vf) : h.centroid_mean_mm, a.faces, raster, mesh);
      if (sigma && std::abs(a.sum_vf) > 0) {
        const Vec3 cop = a.cp / a.sum_vf;
        const double trace = a.k2 - 2 * cop.dot(a.k1) + cop.squaredNorm() * a.k0;
        // No weighing texel with a known σ (all saturated: lower bounds): the σ is unknown, not 0.
        if (a.k0 > 0) h.centre_of_pressure_sigma_mm = std::sqrt(std::max(0.0, trace)) / std::abs(a.sum_vf);
      }
      if (sigma && a.m0 > 0) {  // else no outline texel within its σ of the threshold: unknown, not 0
        const Vec3& c = h.centroid_mean_mm;
        h.centroid_sigma_mm = std::sqrt(std::max(0.0, a.m2 - 2 * c.dot(a.m1) + c.squaredNorm() * a.m0)) / a.sum_w;
      }
    } else {
      h.centroid_mm = h.centroid_mean_mm = h.centre_of_pressure_mm = Vec3::Constant(kNaN);
    }
    h.texels = a.texels;
    h.flagged_texels = a.flagged;
    h.unseen_area_mm2 = a.unseen;
    found.push_back(std::move(h));
  }
  std::sort(found.begin(), found.end(), [](const Hotspot& x, const Hotspot& y) { return x.peak > y.peak; });
  std::vector<int> relabel(n, 0);
  for (std::size_t k = 0; k < found.size(); ++k) {
    relabel[found[k].id] = static_cast<int>(k) + 1;
    found[k].id = static_cast<int>(k) + 1;
  }
  if (labels)
    for (int j = 0; j < g.height; ++j)
      for (int i = 0; i < g.width; ++i) {
        const float v = field.value[g.index(i, j)];
        if (std::isfinite(v) && v >= thresholds.front()) (*labels)[g.index(i, j)] = relabel[lab.at<int>(j, i)];
      }
  return found;
}

}  // namespace clearfit
