#pragma once
// A 24 × 18 × 3 mm slab seen from 60 mm by a 320 × 240 pinhole camera (about
// 11.7 px/mm), traced with its chart: the small scene the simulator tests render.
#include <clearfit/geometry/shapes.hpp>

#include "trace_part.hpp"

namespace clearfit::test {

struct SlabView {
  TracePart part{shapes::slab(24, 18, 3, 4)};
  Chart chart;
  CameraModel camera;
  Rigid3 cam_from_part;
  RefractionMap map;
  explicit SlabView(double medium_ior = 1.0) {
    chart = compute_chart(part.mesh, part.contact);
    camera.lensmodel = "LENSMODEL_PINHOLE";
    camera.intrinsics = {700, 700, 159.5, 119.5};
    camera.width = 320, camera.height = 240;
    cam_from_part.rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();
    cam_from_part.translation = Vec3(0, 0, 60);
    MapOptions o;
    o.indices.n_medium = medium_ior;
    TraceScene sc = part.scene();
    sc.chart = &chart;
    map = compute_refraction_map(sc, camera, cam_from_part, o);
  }
};

}  // namespace clearfit::test
