// The not-worn capture's map (baseline_map.hpp) against closed forms: through
// a flat slab in air a ray leaves the contact face parallel to the camera ray
// (two parallel interfaces), so the held skin point is the worn contact point
// plus the camera direction scaled to the gap; without the part the camera
// ray meets the plane z = -gap. On a cylindrical shell the skin lies on the
// cylinder of radius r_in - gap.
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/refraction/baseline_map.hpp>
#include <gtest/gtest.h>

#include "../support/slab_view.hpp"

#include <cmath>

using namespace clearfit;

namespace {

MapOptions air() {
  MapOptions o;
  o.indices.n_medium = 1.0;
  return o;
}

Vec3 camera_direction(const test::SlabView& v, int x, int y) {
  return v.cam_from_part.rotation.transpose() * v.camera.unproject(Vec2(x, y)).normalized();
}

TEST(BaselineMap, HeldOffAFlatSlabShiftsAlongTheCameraRay) {
  const test::SlabView v;
  TraceScene sc = v.part.scene();
  sc.chart = &v.chart;
  for (double gap : {0.5, 1.0, 3.0}) {
    const RefractionMap b = compute_baseline_map(sc, v.camera, v.cam_from_part, air(), BaselinePart::held, gap, v.map);
    long long checked = 0;
    double worst = 0, worst_uv = 0;
    for (int y = 0; y < v.camera.height; y += 7)
      for (int x = 0; x < v.camera.width; x += 7) {
        const auto p = v.map.index(x, y);
        if (v.map.status[p] != PixelStatus::valid || b.status[p] != PixelStatus::valid) continue;
        const Vec3 d = camera_direction(v, x, y);
        const Vec3 expected = v.map.skin_point[p] + d * (gap / -d.z());
        worst = std::max(worst, (b.skin_point[p] - expected).norm());
        // Its chart uv is that of the contact point straight above it (planar chart: the x-y projection).
        const Vec3 above(expected.x(), expected.y(), 0);
        const Vec2 uv((above - v.chart.origin).dot(v.chart.axis_u), (above - v.chart.origin).dot(v.chart.axis_v));
        worst_uv = std::max(worst_uv, (b.chart_uv[p].cast<double>() - uv).norm());
        ++checked;
      }
    EXPECT_GT(checked, 500) << gap;
    EXPECT_LT(worst, 1e-9) << "gap " << gap;
    EXPECT_LT(worst_uv, 1e-5) << "gap " << gap;  // float chart uv
    EXPECT_GT(b.stats.by_status[0], 0.8 * v.map.stats.by_status[0]);
  }
}

TEST(BaselineMap, AbsentPartSeesTheSkinPlaneStraight) {
  const test::SlabView v;
  TraceScene sc = v.part.scene();
  sc.chart = &v.chart;
  const double gap = 1.5;
  const RefractionMap b = compute_baseline_map(sc, v.camera, v.cam_from_part, air(), BaselinePart::absent, gap, v.map);
  const Vec3 eye = v.cam_from_part.inverse().translation;
  long long checked = 0;
  double worst = 0;
  for (int y = 0; y < v.camera.height; y += 5)
    for (int x = 0; x < v.camera.width; x += 5) {
      const auto p = b.index(x, y);
      if (b.status[p] != PixelStatus::valid) continue;
      const Vec3 d = camera_direction(v, x, y);
      const Vec3 expected = eye + d * ((-gap - eye.z()) / d.z());
      worst = std::max(worst, (b.skin_point[p] - expected).norm());
      EXPECT_NEAR(b.transmittance[p], optics::fresnel(-d.z(), 1.0, 1.4).T, 1e-5);
      ++checked;
    }
  EXPECT_GT(checked, 1000);
  EXPECT_LT(worst, 1e-9);
}

TEST(BaselineMap, ZeroGapHeldSeesTheWornContactPoints) {
  const test::SlabView v;
  TraceScene sc = v.part.scene();
  sc.chart = &v.chart;
  const RefractionMap b = compute_baseline_map(sc, v.camera, v.cam_from_part, air(), BaselinePart::held, 0.0, v.map);
  long long same = 0;
  for (std::size_t p = 0; p < b.status.size(); ++p)
    if (b.status[p] == PixelStatus::valid) {
      ASSERT_EQ(v.map.status[p], PixelStatus::valid);
      EXPECT_LT((b.skin_point[p] - v.map.skin_point[p]).norm(), 1e-12);
      ++same;
    }
  EXPECT_GT(same, 0.8 * v.map.stats.by_status[0]);
  // Part -> air transmits less than part -> skin.
  const auto c = v.map.index(160, 120);
  EXPECT_LT(b.transmittance[c], v.map.transmittance[c]);
}

TEST(BaselineMap, HeldOffACylinderMeetsTheInnerCylinderMinusTheGap) {
  test::TracePart part(shapes::cylindrical_shell(30, 33, 60, 20, 96, 8));
  const Chart chart = compute_chart(part.mesh, part.contact);
  CameraModel camera;
  camera.lensmodel = "LENSMODEL_PINHOLE";
  camera.intrinsics = {500, 500, 159.5, 119.5};
  camera.width = 320, camera.height = 240;
  Rigid3 cam_from_part;
  cam_from_part.rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();
  cam_from_part.translation = Vec3(0, 0, 100);
  TraceScene sc = part.scene();
  sc.chart = &chart;
  const RefractionMap worn = compute_refraction_map(sc, camera, cam_from_part, air());
  const double gap = 2.0, sagitta = 30 * (1 - std::cos(M_PI / 96 * 60 / 360 * 2 / 2));
  const RefractionMap b = compute_baseline_map(sc, camera, cam_from_part, air(), BaselinePart::held, gap, worn);
  long long n = 0;
  for (std::size_t p = 0; p < b.status.size(); ++p) {
    if (b.status[p] != PixelStatus::valid) continue;
    const Vec3& q = b.skin_point[p];
    const double r = std::hypot(q.x(), q.z());
    EXPECT_LE(r, 30 - gap + 1e-9);
    EXPECT_GE(r, 30 - gap - 2 * sagitta);
    ++n;
  }
  EXPECT_GT(n, 0.5 * worn.stats.by_status[0]);
}

TEST(BaselineMap, NegativeGapIsRefused) {
  const test::SlabView v;
  EXPECT_THROW(SkinSurface::offset(v.part.mesh, v.part.contact, -0.1), std::invalid_argument);
  EXPECT_THROW(SkinSurface::offset(v.part.mesh, v.part.contact, std::nan("")), std::invalid_argument);
}

}  // namespace
