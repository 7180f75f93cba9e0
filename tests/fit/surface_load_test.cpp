// Sources given in the part frame land on the 3D contact surface: a flat
// punch on a bump's face loads the face with Sneddon's closed form at the 3D
// distance from its axis, its rim at the face's edge, and nothing on the wall
// or the plate, whatever the LSCM chart does to the face's size. On the
// study plate and on a smaller synthetic bump.
#include <clearfit/fit/contact_mechanics.hpp>
#include <clearfit/fit/hotspots.hpp>
#include <clearfit/fit/simulate.hpp>
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/import.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <unistd.h>

#include "../support/bump_part.hpp"

namespace clearfit::sim {
namespace {
namespace fs = std::filesystem;

struct Part {
  Mesh mesh;
  ContactSurface contact;
  Chart chart;
  explicit Part(const fs::path& obj) {
    mesh = load_mesh(obj);
    ContactSelector s;
    s.group = "contact";
    contact = select_contact(mesh, s);
    ChartOptions o;
    o.method = ChartMethod::lscm;
    chart = compute_chart(mesh, contact, o);
  }
};

fs::path synthetic_obj(const test::BumpPlate& b) {
  const fs::path p = fs::temp_directory_path() / ("clearfit_bump_" + std::to_string(::getpid()) + ".obj");
  std::ofstream(p) << test::bump_plate_obj(b);
  return p;
}

void expect_punch_on_the_face(const Part& part, double radius, double height, double texel_mm) {
  PressureSource punch;
  punch.kind = PressureSource::Kind::punch;
  punch.name = "bump";
  punch.center_part_mm = Vec3(0, 0, -height - 0.4);  // below the face: moved onto it
  punch.radius_mm = radius;
  punch.force_n = 0.19;
  PressureFieldSpec spec;
  spec.sources = {punch};
  spec.texel_mm = texel_mm;
  const PressureTruth t = make_pressure_truth(part.mesh, part.contact, part.chart, spec);
  const ChartRaster raster = rasterize_chart(part.mesh, part.chart, t.pressure.grid);
  const contact::FlatPunch closed{radius, 0.19, punch.rim_cap_ratio};
  const Vec3 axis(0, 0, 0);
  double face_chart_area = 0, face_area = 0, loaded_off_face = 0, worst = 0;
  for (std::size_t k = 0; k < raster.face.size(); ++k) {
    if (raster.face[k] < 0) continue;
    const Vec3& x = raster.point[k];
    const float p = t.pressure.value[k];
    ASSERT_TRUE(std::isfinite(p));
    const bool on_face = std::abs(x.z() + height) < 1e-6;
    if (on_face) {
      const Vec3 d = x - axis;
      const double expected = closed.pressure_kpa(std::hypot(d.x(), d.y()));
      worst = std::max(worst, std::abs(p - expected) / expected);
      face_chart_area += texel_mm * texel_mm;
      face_area += raster.area_mm2[k];
    } else {
      loaded_off_face = std::max(loaded_off_face, static_cast<double>(p));
    }
  }
  const double chart_scale = std::sqrt(face_chart_area / face_area);
  std::printf("face: chart/3D length %.3f, worst relative error %.2e, most off the face %.3g kPa\n", chart_scale, worst, loaded_off_face);
  EXPECT_LT(chart_scale, 0.9);  // the chart shrinks the face: chart distances would be wrong
  EXPECT_LT(worst, 1e-4);       // Sneddon at the 3D distance from the axis
  EXPECT_EQ(loaded_off_face, 0.0);  // wall and plate carry nothing
  ASSERT_EQ(t.hotspots.size(), 1u);
  const double disk = std::numbers::pi * radius * radius;
  EXPECT_NEAR(t.hotspots[0].area_above_5_5_mm2, disk, 0.03 * disk);  // skin area, not chart area
  ASSERT_TRUE(t.hotspots[0].centroid_part_mm);
  EXPECT_LT((*t.hotspots[0].centroid_part_mm - Vec3(0, 0, -height)).norm(), 0.01);
}

TEST(SurfaceLoad, PunchOnTheStudyPlateBumpLoadsItsFaceOnly) {
  const Part part(fs::path(CLEARFIT_SAMPLES_DIR) / "study-plate" / "study-plate.obj");
  expect_punch_on_the_face(part, 2.0, 1.0, 0.04);
}

TEST(SurfaceLoad, PunchOnASmallerBumpLoadsItsFaceOnly) {
  test::BumpPlate b;
  b.half = 3, b.thickness = 1.5, b.radius = 1.0, b.height = 0.5, b.around = 64;
  const fs::path obj = synthetic_obj(b);
  const Part part(obj);
  fs::remove(obj);
  expect_punch_on_the_face(part, 1.0, 0.5, 0.02);
}

TEST(SurfaceLoad, GaussianUsesTheDistanceOnThePartAndSparesWallsTurnedAway) {
  PressureSource g;
  g.name = "g";
  g.peak_kpa = 10, g.sigma_mm = 0.8;
  const SurfaceLoad load = SurfaceLoad::at(g, SurfacePoint{Vec3(0, 0, -1), Vec2::Zero(), 0, 0}, Vec3(0, 0, -1));
  EXPECT_NEAR(load.pressure_kpa(Vec3(0.6, 0.8, -1), Vec3(0, 0, -1)), 10 * std::exp(-1 / (2 * 0.64)), 1e-9);
  EXPECT_NEAR(load.pressure_kpa(Vec3(0, 0, -2), Vec3(0, 0.6, -0.8)), 10 * std::exp(-1 / (2 * 0.64)), 1e-9);  // 37° off: loaded
  EXPECT_EQ(load.pressure_kpa(Vec3(1, 0, -0.5), Vec3(1, 0, 0)), 0.0);  // a wall, edge-on to the load
}

}  // namespace
}  // namespace clearfit::sim
