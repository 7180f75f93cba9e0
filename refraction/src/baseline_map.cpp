// The not-worn capture's own map (baseline_map.hpp): exit rays traced once,
// then cast onto the skin moved by the gap.
#include "map_stages.hpp"

#include <clearfit/refraction/baseline_map.hpp>

#include <tbb/parallel_for.h>

#include <cmath>
#include <stdexcept>

namespace clearfit {

using namespace refraction_detail;

const char* to_string(BaselinePart part) {
  switch (part) {
    case BaselinePart::held: return "held";
    case BaselinePart::absent: return "absent";
    case BaselinePart::touching: return "touching";
  }
  return "?";
}

SkinSurface SkinSurface::offset(const Mesh& part, const ContactSurface& contact, double gap_mm) {
  if (!(std::isfinite(gap_mm) && gap_mm >= 0))
    throw std::invalid_argument("SkinSurface::offset: gap_mm = " + std::to_string(gap_mm) + ": must be a finite length >= 0");
  // Angle-weighted vertex normals over the contact faces.
  std::vector<Vec3> normal(part.vertices.size(), Vec3::Zero());
  for (int f : contact.faces) {
    const Vec3 n = part.face_normal(f);
    for (int k = 0; k < 3; ++k) {
      const Vec3 a = part.corner(f, (k + 1) % 3) - part.corner(f, k), b = part.corner(f, (k + 2) % 3) - part.corner(f, k);
      normal[part.faces[f][k]] += optics::angle_between(a, b) * n;
    }
  }
  SkinSurface s;
  std::vector<int> vertex(part.vertices.size(), -1);
  for (int f : contact.faces) {
    std::array<int, 3> face{};
    for (int k = 0; k < 3; ++k) {
      int& v = vertex[part.faces[f][k]];
      if (v < 0) {
        const Vec3& n = normal[part.faces[f][k]];
        v = s.mesh.num_vertices();
        s.mesh.vertices.push_back(part.vertices[part.faces[f][k]] + (n.norm() > 0 ? Vec3(gap_mm * n.normalized()) : Vec3::Zero()));
      }
      face[k] = v;
    }
    s.mesh.faces.push_back({face[0], face[2], face[1]});  // reversed: the skin's normal points out of the body
    s.mesh.file_face.push_back(f);
    s.part_face.push_back(f);
  }
  s.mesh.source = part.source;
  s.index = make_ray_index(s.mesh);
  return s;
}

BaselineRays::BaselineRays(const TraceScene& scene, const CameraModel& camera, const Rigid3& cam_from_part, const MapOptions& options,
                           BaselinePart part, const RefractionMap& worn)
    : scene_(scene), part_(part), n_(options.indices), width_(camera.width), height_(camera.height) {
  if (part == BaselinePart::touching) throw std::invalid_argument("BaselineRays: a touching baseline uses the worn map");
  if (worn.width != camera.width || worn.height != camera.height)
    throw std::invalid_argument("BaselineRays: the worn map is not of this camera");
  options.validate();
  check_scene(scene);
  worn_status_.assign(worn.status.begin(), worn.status.end());
  for (std::size_t p = 0; p < worn_status_.size(); ++p) {
    const PixelStatus s = worn_status_[p];
    const bool take = part == BaselinePart::held ? s == PixelStatus::valid || s == PixelStatus::contact_tir
                                                 : s != PixelStatus::outside && s != PixelStatus::no_ray;
    if (take) pixel_.push_back(static_cast<std::uint32_t>(p));
  }
  const std::shared_ptr<CameraRays> rays = camera_rays(camera);
  rays->ensure(pixel_);
  const Rigid3 part_from_cam = cam_from_part.inverse();
  exit_.resize(pixel_.size());
  for (std::size_t i = 0; i < pixel_.size(); ++i)
    exit_[i] = Ray{part_from_cam.translation, part_from_cam.rotation * rays->ray(pixel_[i])};
  incidence_deg_.assign(pixel_.size(), fnan);
  if (part == BaselinePart::absent) return;
  // Held: the worn trace again, with the gap's medium beyond the contact surface.
  MapOptions o = options;
  o.indices.n_skin = n_.n_medium;
  at_contact_.resize(pixel_.size());
  trace_skin_rays(scene, exit_, at_contact_, o);
  const bool smooth = options.normals == MapOptions::Normals::smooth;
  tbb::parallel_for(std::size_t(0), pixel_.size(), [&](std::size_t i) {
    const SkinSample& s = at_contact_[i];
    incidence_deg_[i] = static_cast<float>(s.incidence_deg);
    if (s.status != PixelStatus::valid) return;
    const Vec3 geometric = scene.mesh->face_normal(s.face);
    Vec3 n = smooth ? scene.index->normals().interpolate(s.face, s.bary[0], s.bary[1], s.bary[2]) : geometric;
    if (n.dot(s.refracted_dir) <= 0) n = geometric;
    const optics::Transmission t = optics::transmit(s.refracted_dir, n, n_.n_part, n_.n_medium);
    exit_[i] = Ray{s.skin_point, t.direction};  // not tir: trace_skin_rays checked the same interface
  });
}

BaselineRays::~BaselineRays() = default;

std::vector<BaselineRays::Landing> BaselineRays::land(double gap_mm, std::span<const std::uint32_t> which) const {
  const bool held = part_ == BaselinePart::held;
  std::vector<Landing> out(which.size());
  // Held at no gap: the skin is the contact surface, where the exit rays start.
  if (held && gap_mm == 0) {
    for (std::size_t k = 0; k < which.size(); ++k) {
      const SkinSample& s = at_contact_[which[k]];
      out[k] = {s.status, s.face, s.bary, s.skin_point, s.contact_deg, s.transmittance};
    }
    return out;
  }
  const SkinSurface skin = SkinSurface::offset(*scene_.mesh, *scene_.contact, gap_mm);
  std::vector<Ray> cast;
  std::vector<std::uint32_t> cast_of;  // index into `which` of each cast ray
  for (std::size_t k = 0; k < which.size(); ++k) {
    const std::uint32_t i = which[k];
    if (held && at_contact_[i].status != PixelStatus::valid) {
      out[k].status = at_contact_[i].status;
      continue;
    }
    Ray r = exit_[i];
    // Leaving the contact surface: the moved skin is gap_mm away, rounding is not.
    r.t_min = held ? 1e-9 * (1 + r.origin.cwiseAbs().maxCoeff()) : 0.0;
    cast.push_back(r);
    cast_of.push_back(static_cast<std::uint32_t>(k));
  }
  std::vector<RayHit> hit(cast.size());
  skin.index->intersect(cast, hit);
  const PixelStatus missed = held ? PixelStatus::exits_elsewhere : PixelStatus::miss;
  tbb::parallel_for(std::size_t(0), cast.size(), [&](std::size_t c) {
    Landing& l = out[cast_of[c]];
    const RayHit& h = hit[c];
    if (!h || !h.front_facing) {
      l.status = missed;
      return;
    }
    const SkinSample* s = held ? &at_contact_[which[cast_of[c]]] : nullptr;
    const double cos_i = std::min(1.0, std::abs(cast[c].direction.normalized().dot(h.geometric_normal)));
    l.status = PixelStatus::valid;
    l.face = skin.part_face[h.face];
    l.bary = {h.bary[0], h.bary[2], h.bary[1]};  // the skin face's corners 1 and 2 are the part face's 2 and 1
    l.point = h.point;
    l.contact_deg = s ? s->contact_deg : std::acos(cos_i) * kRadToDeg;
    l.transmittance = (s ? s->transmittance : 1.0) * (n_.n_medium != n_.n_skin ? optics::fresnel(cos_i, n_.n_medium, n_.n_skin).T : 1.0);
  });
  return out;
}

std::vector<Vec2> BaselineRays::chart_uv(double gap_mm, std::span<const std::uint32_t> which) const {
  if (!scene_.chart || scene_.chart->uv.empty()) throw std::invalid_argument("BaselineRays::chart_uv: the scene has no chart");
  const std::vector<Landing> l = land(gap_mm, which);
  std::vector<Vec2> uv(which.size(), Vec2::Constant(std::numeric_limits<double>::quiet_NaN()));
  for (std::size_t k = 0; k < which.size(); ++k)
    if (l[k].status == PixelStatus::valid) {
      const auto& f = scene_.mesh->faces[l[k].face];
      uv[k] = l[k].bary[0] * scene_.chart->uv[f[0]] + l[k].bary[1] * scene_.chart->uv[f[1]] + l[k].bary[2] * scene_.chart->uv[f[2]];
    }
  return uv;
}

RefractionMap BaselineRays::map(double gap_mm) const {
  const auto t0 = Clock::now();
  if (!(std::isfinite(gap_mm) && gap_mm >= 0))
    throw std::invalid_argument("BaselineRays::map: gap_mm = " + std::to_string(gap_mm) + ": must be a finite length >= 0");
  RefractionMap m;
  allocate(m, width_, height_);
  for (std::size_t p = 0; p < worn_status_.size(); ++p) reset_span(m, p, 1, worn_status_[p]);
  std::vector<std::uint32_t> all(pixel_.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<std::uint32_t>(i);
  const std::vector<Landing> l = land(gap_mm, all);
  tbb::parallel_for(std::size_t(0), l.size(), [&](std::size_t i) {
    const std::size_t p = pixel_[i];
    m.status[p] = l[i].status;
    m.incidence_deg[p] = incidence_deg_[i];
    if (l[i].status != PixelStatus::valid) return;
    m.skin_point[p] = l[i].point;
    m.face[p] = l[i].face;
    m.bary[p] = Eigen::Vector2f(static_cast<float>(l[i].bary[1]), static_cast<float>(l[i].bary[2]));
    m.contact_deg[p] = static_cast<float>(l[i].contact_deg);
    m.transmittance[p] = static_cast<float>(l[i].transmittance);
    if (scene_.chart && !scene_.chart->uv.empty()) {
      const auto& f = scene_.mesh->faces[l[i].face];
      const Vec2 uv = l[i].bary[0] * scene_.chart->uv[f[0]] + l[i].bary[1] * scene_.chart->uv[f[1]] + l[i].bary[2] * scene_.chart->uv[f[2]];
      m.chart_uv[p] = uv.cast<float>();
    }
  });
  MapStats& st = m.stats;
  st.pixels = static_cast<long long>(m.status.size());
  st.traced = static_cast<long long>(pixel_.size());
  st.mode = "exact";
  count_statuses(m);
  st.trace_ms = st.total_ms = ms_since(t0);
  return m;
}

RefractionMap compute_baseline_map(const TraceScene& scene, const CameraModel& camera, const Rigid3& cam_from_part,
                                   const MapOptions& options, BaselinePart part, double gap_mm, const RefractionMap& worn) {
  if (part == BaselinePart::touching) return worn;
  return BaselineRays(scene, camera, cam_from_part, options, part, worn).map(gap_mm);
}

}  // namespace clearfit
