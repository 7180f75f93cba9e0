#pragma once
// Point location in a contact chart: chart coordinates (mm) -> face and
// barycentrics, through a uniform grid over the charted triangles. Used to
// put interpolated chart coordinates back onto the mesh surface exactly.
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/mesh.hpp>

#include <optional>

namespace clearfit::refraction_detail {

struct ChartHit {
  int face = -1;
  std::array<double, 3> bary{};
  Vec3 point;  ///< on the mesh, part frame
};

class ChartLocator {
 public:
  ChartLocator(const Mesh& mesh, const Chart& chart);
  /// The charted face containing `uv` (barycentrics within [-1e-9, 1]), or nullopt.
  std::optional<ChartHit> locate(const Vec2& uv) const;
  /// The same, trying face `hint` first (the previous pixel's face: along a
  /// row most pixels fall in the face of the one before).
  std::optional<ChartHit> locate(const Vec2& uv, int hint) const;

 private:
  std::optional<ChartHit> in_face(const Vec2& uv, int f) const;
  const Mesh& mesh_;
  const Chart& chart_;
  Vec2 lo_ = Vec2::Zero();
  double cell_ = 1;
  int nx_ = 0, ny_ = 0;
  std::vector<int> start_, faces_;  // CSR: faces overlapping each cell
  // Per mesh face (charted ones set): chart corner 0 and the inverse of the
  // 2x2 matrix of its edges, row-major; barycentrics 1, 2 = inverse · (uv - corner 0).
  struct Affine {
    Vec2 a;
    double m[4];
  };
  std::vector<Affine> affine_;
};

}  // namespace clearfit::refraction_detail
