#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/refraction/map_cache.hpp>

#include <cstring>
#include <fstream>
#include <string_view>

namespace clearfit {
namespace {

constexpr char kMagic[8] = {'C', 'F', 'M', 'A', 'P', '0', '0', '1'};
// Bumped when compute_refraction_map's results change for the same inputs
// (2: the adaptive mode's boundary resolver; 3: four checks per cell and the
// parent's estimate; 4: checks off node rows in short cells, parents far above
// the tolerance not trusted; 5: four drawn checks more per cell, one entry
// face per accepted cell with flat normals; 6: the seen fraction of the outline's pixels), so older
// cached maps are not reused.
constexpr int kMapAlgorithm = 6;

struct Fnv {
  std::uint64_t h = 14695981039346656037ull;
  void bytes(const void* p, std::size_t n) {
    const auto* c = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) h = (h ^ c[i]) * 1099511628211ull;
  }
  template <class T>
  void value(const T& v) { bytes(&v, sizeof v); }
  template <class T>
  void vec(const std::vector<T>& v) {
    value(v.size());
    if (!v.empty()) bytes(v.data(), v.size() * sizeof(T));
  }
};

std::filesystem::path entry(const std::filesystem::path& dir, std::uint64_t key) {
  char name[40];
  std::snprintf(name, sizeof name, "map-%016llx.cfmap", static_cast<unsigned long long>(key));
  return dir / name;
}

// The arrays of a map, in file order, as (pointer, element size, count).
template <class Map, class F>
void for_each_array(Map& m, F&& f) {
  f(m.status.data(), sizeof(PixelStatus), m.status.size());
  f(m.skin_point.data(), sizeof(Vec3), m.skin_point.size());
  f(m.face.data(), sizeof(std::int32_t), m.face.size());
  f(m.bary.data(), sizeof(Eigen::Vector2f), m.bary.size());
  f(m.chart_uv.data(), sizeof(Eigen::Vector2f), m.chart_uv.size());
  f(m.incidence_deg.data(), sizeof(float), m.incidence_deg.size());
  f(m.contact_deg.data(), sizeof(float), m.contact_deg.size());
  f(m.transmittance.data(), sizeof(float), m.transmittance.size());
  f(m.seen_fraction.data(), sizeof(float), m.seen_fraction.size());
}

}  // namespace

std::uint64_t map_inputs_hash(const TraceScene& scene, const CameraModel& camera, const Rigid3& cam_from_part,
                              const MapOptions& o) {
  Fnv f;
  f.bytes(kMagic, sizeof kMagic);
  f.vec(scene.mesh->vertices);
  f.vec(scene.mesh->faces);
  f.vec(scene.contact->is_contact);
  for (const auto& c : scene.index->normals().corner) f.bytes(c.data(), sizeof c);
  f.value(scene.index->backend());
  if (scene.chart) f.vec(scene.chart->uv);
  f.value(camera.intrinsics_hash());
  f.bytes(cam_from_part.rotation.data(), 9 * sizeof(double));
  f.bytes(cam_from_part.translation.data(), 3 * sizeof(double));
  f.value(o.indices.n_medium), f.value(o.indices.n_part), f.value(o.indices.n_skin);
  f.value(o.normals), f.value(o.mode), f.value(o.grid_step), f.value(o.tolerance_um), f.value(o.exact_reasons);
  f.value(kMapAlgorithm);
  f.value(o.fast_paths), f.value(o.cull);
  return f.h;
}

std::optional<RefractionMap> load_cached_map(const std::filesystem::path& dir, std::uint64_t key) {
  std::ifstream in(entry(dir, key), std::ios::binary);
  if (!in) return std::nullopt;
  char magic[8];
  std::uint64_t stored_key = 0;
  std::int32_t w = 0, h = 0;
  in.read(magic, 8);
  in.read(reinterpret_cast<char*>(&stored_key), sizeof stored_key);
  in.read(reinterpret_cast<char*>(&w), sizeof w);
  in.read(reinterpret_cast<char*>(&h), sizeof h);
  if (!in || std::memcmp(magic, kMagic, 8) != 0 || stored_key != key || w <= 0 || h <= 0 || w > 100000 || h > 100000)
    return std::nullopt;
  RefractionMap m;
  m.width = w;
  m.height = h;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  m.status.resize(n), m.skin_point.resize(n), m.face.resize(n), m.bary.resize(n), m.chart_uv.resize(n);
  m.incidence_deg.resize(n), m.contact_deg.resize(n), m.transmittance.resize(n), m.seen_fraction.resize(n);
  for_each_array(m, [&](void* p, std::size_t size, std::size_t count) {
    in.read(static_cast<char*>(p), static_cast<std::streamsize>(size * count));
  });
  std::uint32_t mode_len = 0, path_len = 0;
  in.read(reinterpret_cast<char*>(&m.stats.pixels), sizeof m.stats.pixels);
  in.read(reinterpret_cast<char*>(&m.stats.traced), sizeof m.stats.traced);
  in.read(reinterpret_cast<char*>(m.stats.by_status), sizeof m.stats.by_status);
  in.read(reinterpret_cast<char*>(&m.stats.interpolated), sizeof m.stats.interpolated);
  in.read(reinterpret_cast<char*>(&m.stats.coverage), sizeof m.stats.coverage);
  in.read(reinterpret_cast<char*>(&m.stats.max_error_um), sizeof m.stats.max_error_um);
  in.read(reinterpret_cast<char*>(&m.stats.total_ms), sizeof m.stats.total_ms);
  in.read(reinterpret_cast<char*>(&mode_len), sizeof mode_len);
  if (!in || mode_len > 64) return std::nullopt;
  m.stats.mode.resize(mode_len);
  in.read(m.stats.mode.data(), mode_len);
  in.read(reinterpret_cast<char*>(&path_len), sizeof path_len);
  if (!in || path_len > 64) return std::nullopt;
  m.stats.fast_path.resize(path_len);
  in.read(m.stats.fast_path.data(), path_len);
  if (!in) return std::nullopt;
  for (PixelStatus s : m.status)
    if (static_cast<int>(s) >= kPixelStatusCount) return std::nullopt;
  return m;
}

void store_cached_map(const std::filesystem::path& dir, std::uint64_t key, const RefractionMap& map) {
  if (map.seen_fraction.size() != map.status.size()) return;  // not a whole map of compute_refraction_map's
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InputError(dir.string(), "", "cannot create the cache folder: " + ec.message(), "use --cache DIR or --no-cache");
  write_file_atomically(entry(dir, key), [&](std::ostream& out) {
    const std::int32_t w = map.width, h = map.height;
    out.write(kMagic, 8);
    out.write(reinterpret_cast<const char*>(&key), sizeof key);
    out.write(reinterpret_cast<const char*>(&w), sizeof w);
    out.write(reinterpret_cast<const char*>(&h), sizeof h);
    for_each_array(map, [&](const void* p, std::size_t size, std::size_t count) {
      out.write(static_cast<const char*>(p), static_cast<std::streamsize>(size * count));
    });
    const MapStats& s = map.stats;
    out.write(reinterpret_cast<const char*>(&s.pixels), sizeof s.pixels);
    out.write(reinterpret_cast<const char*>(&s.traced), sizeof s.traced);
    out.write(reinterpret_cast<const char*>(s.by_status), sizeof s.by_status);
    out.write(reinterpret_cast<const char*>(&s.interpolated), sizeof s.interpolated);
    out.write(reinterpret_cast<const char*>(&s.coverage), sizeof s.coverage);
    out.write(reinterpret_cast<const char*>(&s.max_error_um), sizeof s.max_error_um);
    out.write(reinterpret_cast<const char*>(&s.total_ms), sizeof s.total_ms);
    for (const std::string* str : {&s.mode, &s.fast_path}) {
      const auto len = static_cast<std::uint32_t>(str->size());
      out.write(reinterpret_cast<const char*>(&len), sizeof len);
      out.write(str->data(), len);
    }
  });
}

RefractionMap compute_refraction_map_cached(const TraceScene& scene, const CameraModel& camera, const Rigid3& cam_from_part,
                                            const MapOptions& options, const std::filesystem::path& dir, bool* hit) {
  if (hit) *hit = false;
  if (dir.empty()) return compute_refraction_map(scene, camera, cam_from_part, options);
  const std::uint64_t key = map_inputs_hash(scene, camera, cam_from_part, options);
  if (auto cached = load_cached_map(dir, key)) {
    if (hit) *hit = true;
    return std::move(*cached);
  }
  RefractionMap map = compute_refraction_map(scene, camera, cam_from_part, options);
  store_cached_map(dir, key, map);
  return map;
}

}  // namespace clearfit
