#pragma once
// A part ready to trace in tests: mesh, its "contact" group as the contact
// surface, and the default ray index.
#include <clearfit/refraction/map.hpp>

#include <cstdlib>
#include <memory>

namespace clearfit::test {

/// The factor on the ray counts of the stress tests: $CLEARFIT_RAY_TEST_SCALE (default 1; 0.1 under
/// the sanitizers, 10 and more in scripts/numerical-sweep.sh).
inline double ray_test_scale() {
  const char* s = std::getenv("CLEARFIT_RAY_TEST_SCALE");
  return s ? std::atof(s) : 1.0;
}

struct TracePart {
  Mesh mesh;
  ContactSurface contact;
  std::unique_ptr<RayIndex> index;
  explicit TracePart(Mesh m) : mesh(std::move(m)) {
    ContactSelector s;
    s.group = "contact";
    contact = select_contact(mesh, s);
    index = make_ray_index(mesh);
  }
  TraceScene scene() const { return {&mesh, &contact, index.get(), nullptr}; }
};

}  // namespace clearfit::test
