// Stage 2 of the refraction map: ray -> skin sample (first cast, Snell at
// entry, second cast, Snell and Fresnel at the contact).
#include "flat_slab.hpp"
#include "map_stages.hpp"

#include <clearfit/error.hpp>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>

namespace clearfit::refraction_detail {

namespace {

// Smallest t at which a ray leaving a point computed on `face` can no longer
// re-hit that face's plane through rounding: the point (computed as
// origin + t·d of the incoming ray) is off the plane by at most a few ulp of
// the largest magnitude involved (its coordinates, the face's vertices, the
// incoming ray's origin and length); along a direction making cosine `cos_n`
// with the plane's normal that becomes a distance / cos_n.
double leave_surface_t(const Mesh& mesh, int face, const Vec3& point, double cos_n, double incoming_scale) {
  double scale = std::max(point.cwiseAbs().maxCoeff(), incoming_scale);
  for (int k = 0; k < 3; ++k) scale = std::max(scale, mesh.corner(face, k).cwiseAbs().maxCoeff());
  const double err = 16 * std::numeric_limits<double>::epsilon() * scale;
  return err / std::max(cos_n, 1e-6);
}

}  // namespace

void check_scene(const TraceScene& scene) {
  if (!scene.mesh || !scene.contact || !scene.index)
    throw std::invalid_argument("refraction: TraceScene needs mesh, contact and index");
  if (static_cast<int>(scene.contact->is_contact.size()) != scene.mesh->num_faces())
    throw std::invalid_argument("refraction: the contact surface belongs to another mesh");
  if (scene.contact->faces.empty())
    throw InputError(scene.mesh->source, "contact surface", "has no faces", "choose the faces the skin touches");
}

Tracer::Tracer(const TraceScene& scene, const MapOptions& opt)
    : scene_(scene), n_(opt.indices), smooth_(opt.normals == MapOptions::Normals::smooth),
      index_matched_(opt.fast_paths && opt.indices.n_medium == opt.indices.n_part) {
  if (opt.fast_paths) slab_ = FlatSlab::detect(*scene.mesh, *scene.contact, scene.index->normals());
}

Tracer::~Tracer() = default;

std::string Tracer::fast_path() const {
  std::string s = index_matched_ ? "index-matched" : "";
  if (slab_) s += s.empty() ? "flat-slab" : "+flat-slab";
  return s.empty() ? "none" : s;
}

bool Tracer::enter(const Ray& first, const RayHit& h, SkinSample& s, Ray& second) const {
  if (first.direction.isZero() || !first.direction.allFinite() || !first.origin.allFinite())
    return fail(s, PixelStatus::no_ray);
  if (!h) return fail(s, PixelStatus::miss);
  if (!h.front_facing) return fail(s, PixelStatus::back_face);
  if (scene_.contact->is_contact[h.face]) return fail(s, PixelStatus::contact_first);
  const Vec3 d = first.direction.normalized();
  Vec3 nrm = smooth_ ? h.shading_normal : h.geometric_normal;
  if (nrm.dot(d) >= 0) nrm = h.geometric_normal;  // shading normal turned away near a silhouette
  s.entry_point = h.point;
  s.entry_face = h.face;
  s.entry_normal = nrm;
  s.incidence_deg = optics::angle_between(-d, nrm) * kRadToDeg;
  Vec3 d2 = d;
  s.transmittance = 1;
  if (!index_matched_) {
    const optics::Transmission t = optics::transmit(d, nrm, n_.n_medium, n_.n_part);
    if (t.tir) return fail(s, PixelStatus::entry_tir);
    s.transmittance = optics::fresnel(t, n_.n_medium, n_.n_part).T;
    d2 = t.direction;
  }
  s.refracted_dir = d2;
  second.origin = h.point;
  second.direction = d2;
  const double incoming = first.origin.cwiseAbs().maxCoeff() + std::abs(h.t) * first.direction.norm();
  second.t_min = leave_surface_t(*scene_.mesh, h.face, h.point, std::abs(d2.dot(h.geometric_normal)), incoming);
  second.t_max = std::numeric_limits<double>::infinity();
  second.skip_face = h.face;  // a ray cannot meet the plane it leaves again
  return true;
}

void Tracer::reach(const RayHit& h, SkinSample& s) const {
  if (!h || !scene_.contact->is_contact[h.face]) { fail(s, PixelStatus::exits_elsewhere); return; }
  const Vec3& d2 = s.refracted_dir;
  Vec3 nrm = smooth_ ? h.shading_normal : h.geometric_normal;
  if (nrm.dot(d2) <= 0) nrm = h.geometric_normal;
  s.contact_deg = optics::angle_between(d2, nrm) * kRadToDeg;
  if (n_.n_part != n_.n_skin) {
    const optics::Transmission t = optics::transmit(d2, nrm, n_.n_part, n_.n_skin);
    if (t.tir) { fail(s, PixelStatus::contact_tir); return; }
    s.transmittance *= optics::fresnel(t, n_.n_part, n_.n_skin).T;
  }
  s.status = PixelStatus::valid;
  s.skin_point = h.point;
  s.face = h.face;
  s.bary = h.bary;
}

void Tracer::trace(std::span<const Ray> first, std::span<SkinSample> out) const {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, first.size(), kChunk), [&](const auto& r) {
    for (std::size_t b = r.begin(); b < r.end(); b += kChunk) {
      const std::size_t n = std::min(kChunk, r.end() - b);
      trace_chunk(first.subspan(b, n), out.subspan(b, n));
    }
  });
}

void Tracer::trace_chunk(std::span<const Ray> first, std::span<SkinSample> out) const {
  Scratch w;  // per call: a nested parallel_for in intersect() may run another chunk on this thread
  const std::size_t n = first.size();
  w.hit.resize(n);
  w.which.clear();
  // Rays without a usable direction (the lens could not unproject) are not cast.
  for (std::size_t i = 0; i < n; ++i) {
    w.hit[i] = RayHit{};
    if (first[i].direction.isZero() || !first[i].direction.allFinite() || !first[i].origin.allFinite()) continue;
    if (slab_)  // closed form where the ray enters through the outer plane; the rest go to the index
      if (auto h = slab_->enter(first[i])) {
        w.hit[i] = *h;
        continue;
      }
    w.which.push_back(static_cast<std::uint32_t>(i));
  }
  cast(first, w);
  w.second.resize(n);
  w.which.clear();
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = SkinSample{};
    if (!enter(first[i], w.hit[i], out[i], w.second[i])) continue;
    if (slab_)
      if (auto h = slab_->reach(w.second[i])) {
        reach(*h, out[i]);
        continue;
      }
    w.which.push_back(static_cast<std::uint32_t>(i));
  }
  cast(w.second, w);
  for (std::uint32_t i : w.which) reach(w.hit[i], out[i]);
}

void Tracer::cast(std::span<const Ray> rays, Scratch& w) const {
  if (w.which.empty()) return;
  if (w.which.size() == rays.size()) {
    scene_.index->intersect(rays, std::span<RayHit>(w.hit.data(), rays.size()));
    return;
  }
  w.cast_ray.resize(w.which.size());
  w.cast_hit.resize(w.which.size());
  for (std::size_t k = 0; k < w.which.size(); ++k) w.cast_ray[k] = rays[w.which[k]];
  scene_.index->intersect(w.cast_ray, w.cast_hit);
  for (std::size_t k = 0; k < w.which.size(); ++k) w.hit[w.which[k]] = w.cast_hit[k];
}

}  // namespace clearfit::refraction_detail
