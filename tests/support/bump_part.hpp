#pragma once
// A flat plate with one cylindrical bump on its skin side, as an OBJ text:
// the study's setup (samples/study-plate/make_mesh.py builds the sample the
// same way) at any size. The contact surface (group `contact`) runs from the
// bump face (z = -height) down its wall (r = radius) to the plate's underside
// (z = 0): one topological disk with a wall between two contact faces.
// Groups `outer` (top, z = thickness, the camera side) and `side` (rim).
#include <cmath>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

namespace clearfit::test {

struct BumpPlate {
  double half = 6.0, thickness = 3.0, radius = 2.0, height = 1.0;  ///< mm
  int around = 96, rings_face = 8, rings_wall = 4, rings_plate = 10;
};

inline std::string bump_plate_obj(const BumpPlate& b) {
  std::ostringstream v, f_outer, f_side, f_contact;
  v.precision(9);
  int count = 0;
  auto vertex = [&](double x, double y, double z) {
    v << "v " << x << ' ' << y << ' ' << z << '\n';
    return ++count;
  };
  const int n = b.around;
  std::vector<double> angle(n);
  for (int k = 0; k < n; ++k) angle[k] = 2 * std::numbers::pi * k / n;
  auto square = [&](double a) {  // the plate's square rim in direction a
    const double t = b.half / std::max(std::abs(std::cos(a)), std::abs(std::sin(a)));
    return std::pair{std::cos(a) * t, std::sin(a) * t};
  };
  auto plate_ring = [&](double t, double z) {
    std::vector<int> ring;
    for (double a : angle) {
      const auto [sx, sy] = square(a);
      ring.push_back(vertex((1 - t) * b.radius * std::cos(a) + t * sx, (1 - t) * b.radius * std::sin(a) + t * sy, z));
    }
    return ring;
  };
  auto tri = [](std::ostringstream& o, int a, int c, int d) { o << "f " << a << ' ' << c << ' ' << d << '\n'; };
  auto band = [&](std::ostringstream& o, const std::vector<int>& a, const std::vector<int>& c) {
    for (int k = 0; k < n; ++k) {
      const int k1 = (k + 1) % n;
      tri(o, a[k], a[k1], c[k1]);
      tri(o, a[k], c[k1], c[k]);
    }
  };
  // Contact, from the bump's centre outwards (faces seen from below, -z).
  const int centre = vertex(0, 0, -b.height);
  std::vector<std::vector<int>> rings;
  for (int i = 1; i <= b.rings_face; ++i) {
    const double r = b.radius * i / b.rings_face;
    std::vector<int> ring;
    for (double a : angle) ring.push_back(vertex(r * std::cos(a), r * std::sin(a), -b.height));
    rings.push_back(ring);
  }
  for (int i = 1; i <= b.rings_wall; ++i) {
    const double z = -b.height + b.height * i / b.rings_wall;
    std::vector<int> ring;
    for (double a : angle) ring.push_back(vertex(b.radius * std::cos(a), b.radius * std::sin(a), z));
    rings.push_back(ring);
  }
  for (int i = 1; i <= b.rings_plate; ++i) rings.push_back(plate_ring(static_cast<double>(i) / b.rings_plate, 0.0));
  for (int k = 0; k < n; ++k) tri(f_contact, centre, rings[0][(k + 1) % n], rings[0][k]);
  for (std::size_t r = 0; r + 1 < rings.size(); ++r) band(f_contact, rings[r], rings[r + 1]);
  // Rim, then the top from its rim towards the centre (seen from above).
  const std::vector<int>& bottom = rings.back();
  const std::vector<int> top_rim = plate_ring(1.0, b.thickness);
  band(f_side, bottom, top_rim);
  std::vector<std::vector<int>> top{top_rim};
  for (int i = b.rings_plate - 1; i > 0; --i) top.push_back(plate_ring(static_cast<double>(i) / b.rings_plate, b.thickness));
  for (int i = b.rings_face; i > 0; --i) {
    const double r = b.radius * i / b.rings_face;
    std::vector<int> ring;
    for (double a : angle) ring.push_back(vertex(r * std::cos(a), r * std::sin(a), b.thickness));
    top.push_back(ring);
  }
  const int top_centre = vertex(0, 0, b.thickness);
  for (std::size_t r = 0; r + 1 < top.size(); ++r) band(f_outer, top[r], top[r + 1]);
  for (int k = 0; k < n; ++k) tri(f_outer, top_centre, top.back()[k], top.back()[(k + 1) % n]);
  return "# bump plate (tests/support/bump_part.hpp)\n" + v.str() + "g outer\n" + f_outer.str() + "g side\n" + f_side.str() +
         "g contact\n" + f_contact.str();
}

}  // namespace clearfit::test
