#pragma once
// The Embree backend's own options, for benchmarks that compare them
// (bench/ray_index_bench.cpp); make_ray_index uses the defaults.
#include <clearfit/geometry/ray_index.hpp>

#include <memory>

namespace clearfit {

/// How the Embree backend hands rays to Embree (bench/ray_index_bench.cpp measures
/// them: on 200k triangles, camera rays, one thread, stream 4.1, packet16 3.7,
/// single 3.1 Mrays/s; random rays 0.70 / 0.70 / 0.91, all ±40 % on the shared machine).
struct EmbreeOptions {
  enum class Mode { single, packet16, stream } mode = Mode::stream;
  bool high_quality_build = true;   ///< RTC_BUILD_QUALITY_HIGH, else MEDIUM
  bool vertex_guards = true;        ///< guard spheres at the vertices (see ray_index_embree.cpp)
};

/// make_ray_index(mesh, RayBackend::embree, normals) with `options` instead of the defaults.
std::unique_ptr<RayIndex> make_embree_ray_index(const Mesh& mesh, const EmbreeOptions& options,
                                                const CornerNormals* normals = nullptr);

}  // namespace clearfit
