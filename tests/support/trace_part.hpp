#pragma once
// A part ready to trace in tests: mesh, its "contact" group as the contact
// surface, and the default ray index.
#include <clearfit/refraction/map.hpp>

#include <memory>

namespace clearfit::test {

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
