#pragma once
// Refraction maps cached on disk under a hash of everything they depend on
// (mesh, contact faces, chart, normals, camera, pose, options), so a scene
// that did not change reuses its map instead of tracing it again.
#include <clearfit/refraction/map.hpp>

#include <filesystem>
#include <optional>

namespace clearfit {

/// 64-bit FNV-1a hash of the map's inputs and the cache format version.
std::uint64_t map_inputs_hash(const TraceScene& scene, const CameraModel& camera, const Rigid3& cam_from_part,
                              const MapOptions& options);

/// The cached map for `key` in `dir`, or nullopt if absent, unreadable or of
/// another format (a damaged cache entry is ignored, never trusted).
std::optional<RefractionMap> load_cached_map(const std::filesystem::path& dir, std::uint64_t key);

/// Stores `map` under `key` in `dir` (created if missing), atomically.
/// Throws InputError if the folder cannot be created or written.
void store_cached_map(const std::filesystem::path& dir, std::uint64_t key, const RefractionMap& map);

/// compute_refraction_map through the cache in `dir` (no cache if dir is
/// empty). `*hit` (optional) tells whether the map came from the cache.
/// The returned stats are the ones of the run that computed the map.
RefractionMap compute_refraction_map_cached(const TraceScene& scene, const CameraModel& camera,
                                            const Rigid3& cam_from_part, const MapOptions& options,
                                            const std::filesystem::path& dir, bool* hit = nullptr);

}  // namespace clearfit
