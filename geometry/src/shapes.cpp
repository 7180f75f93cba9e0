#include <clearfit/geometry/shapes.hpp>

#include <cmath>
#include <functional>
#include <map>
#include <numbers>
#include <random>
#include <stdexcept>

namespace clearfit::shapes {
namespace {

// Builds a closed mesh from parametric quad patches. Vertices are welded by
// exact coordinates (every patch computes shared points with the same
// expressions), triangles with a repeated vertex (poles) are dropped, and each
// triangle is oriented so its normal agrees with the patch's outward direction.
class Builder {
 public:
  int group(const std::string& name) {
    for (size_t i = 0; i < mesh_.groups.size(); ++i)
      if (mesh_.groups[i] == name) return static_cast<int>(i);
    mesh_.groups.push_back(name);
    return static_cast<int>(mesh_.groups.size()) - 1;
  }
  int vertex(const Vec3& p) {
    auto [it, inserted] = index_.try_emplace({p.x(), p.y(), p.z()}, mesh_.num_vertices());
    if (inserted) mesh_.vertices.push_back(p);
    return it->second;
  }
  void triangle(int a, int b, int c, const Vec3& outward, int g) {
    if (a == b || b == c || a == c) return;
    const Vec3 n = (mesh_.vertices[b] - mesh_.vertices[a]).cross(mesh_.vertices[c] - mesh_.vertices[a]);
    if (n.dot(outward) < 0) std::swap(b, c);
    mesh_.faces.push_back({a, b, c});
    mesh_.face_group.push_back(g);
  }
  /// Patch of nu × nv quads; pos(i, j) for i in [0, nu], j in [0, nv].
  void patch(int nu, int nv, const std::function<Vec3(int, int)>& pos,
             const std::function<Vec3(const Vec3&)>& outward, const std::string& name) {
    const int g = group(name);
    for (int i = 0; i < nu; ++i)
      for (int j = 0; j < nv; ++j) {
        const int a = vertex(pos(i, j)), b = vertex(pos(i + 1, j));
        const int c = vertex(pos(i + 1, j + 1)), d = vertex(pos(i, j + 1));
        const Vec3 m1 = (mesh_.vertices[a] + mesh_.vertices[b] + mesh_.vertices[c]) / 3.0;
        const Vec3 m2 = (mesh_.vertices[a] + mesh_.vertices[c] + mesh_.vertices[d]) / 3.0;
        triangle(a, b, c, outward(m1), g);
        triangle(a, c, d, outward(m2), g);
      }
  }
  Mesh finish(std::string source) {
    mesh_.file_face.resize(mesh_.faces.size());
    for (size_t i = 0; i < mesh_.faces.size(); ++i) mesh_.file_face[i] = static_cast<int>(i);
    mesh_.source = std::move(source);
    return std::move(mesh_);
  }

 private:
  Mesh mesh_;
  std::map<std::array<double, 3>, int> index_;
};

// a + (b - a) k / n, exact at both ends so shared edges weld.
double lerp(double a, double b, int k, int n) {
  if (k <= 0) return a;
  if (k >= n) return b;
  return a + (b - a) * static_cast<double>(k) / n;
}

void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("clearfit::shapes: ") + what);
}

}  // namespace

Mesh box(const Vec3& size, int n) {
  require(size.minCoeff() > 0 && n >= 1, "box needs positive size and n >= 1");
  Builder b;
  const Vec3 h = size / 2;
  auto c = [&](int axis, int k) { return lerp(-h[axis], h[axis], k, n); };
  const char* names[3][2] = {{"xmin", "xmax"}, {"ymin", "ymax"}, {"bottom", "top"}};
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      Vec3 out = Vec3::Zero();
      out[axis] = side ? 1 : -1;
      b.patch(n, n, [&](int i, int j) {
            Vec3 p;
            p[axis] = side ? h[axis] : -h[axis];
            p[u] = c(u, i);
            p[v] = c(v, j);
            return p;
          },
          [&](const Vec3&) { return out; }, names[axis][side]);
    }
  return b.finish("shapes::box");
}

Mesh icosphere(double radius, int subdivisions) {
  require(radius > 0 && subdivisions >= 0 && subdivisions <= 9, "icosphere needs radius > 0, 0 <= subdivisions <= 9");
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                         {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (auto& p : v) p.normalize();
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11},
                                       {1, 5, 9}, {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                       {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8}, {3, 8, 9},
                                       {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      auto key = std::minmax(a, b);
      auto [it, inserted] = mid.try_emplace(key, static_cast<int>(v.size()));
      if (inserted) v.push_back((v[a] + v[b]).normalized());
      return it->second;
    };
    std::vector<std::array<int, 3>> next;
    next.reserve(f.size() * 4);
    for (auto [a, b, c] : f) {
      int ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      next.push_back({a, ab, ca});
      next.push_back({b, bc, ab});
      next.push_back({c, ca, bc});
      next.push_back({ab, bc, ca});
    }
    f = std::move(next);
  }
  Mesh m;
  m.vertices.reserve(v.size());
  for (const auto& p : v) m.vertices.push_back(radius * p);
  m.groups = {"sphere"};
  for (auto tri : f) {
    const Vec3 n = (m.vertices[tri[1]] - m.vertices[tri[0]]).cross(m.vertices[tri[2]] - m.vertices[tri[0]]);
    if (n.dot(m.vertices[tri[0]]) < 0) std::swap(tri[1], tri[2]);
    m.faces.push_back(tri);
  }
  m.face_group.assign(m.faces.size(), 0);
  m.file_face.resize(m.faces.size());
  for (size_t i = 0; i < m.faces.size(); ++i) m.file_face[i] = static_cast<int>(i);
  m.source = "shapes::icosphere";
  return m;
}

Mesh slab(double sx, double sy, double thickness, int n) {
  require(sx > 0 && sy > 0 && thickness > 0 && n >= 1, "slab needs positive sizes and n >= 1");
  Builder b;
  auto x = [&](int i) { return lerp(-sx / 2, sx / 2, i, n); };
  auto y = [&](int j) { return lerp(-sy / 2, sy / 2, j, n); };
  auto z = [&](int k) { return lerp(0.0, thickness, k, 1); };
  b.patch(n, n, [&](int i, int j) { return Vec3(x(i), y(j), z(0)); }, [](const Vec3&) { return Vec3(0, 0, -1); }, "contact");
  b.patch(n, n, [&](int i, int j) { return Vec3(x(i), y(j), z(1)); }, [](const Vec3&) { return Vec3(0, 0, 1); }, "outer");
  b.patch(n, 1, [&](int i, int k) { return Vec3(x(i), y(0), z(k)); }, [](const Vec3&) { return Vec3(0, -1, 0); }, "side");
  b.patch(n, 1, [&](int i, int k) { return Vec3(x(i), y(n), z(k)); }, [](const Vec3&) { return Vec3(0, 1, 0); }, "side");
  b.patch(n, 1, [&](int j, int k) { return Vec3(x(0), y(j), z(k)); }, [](const Vec3&) { return Vec3(-1, 0, 0); }, "side");
  b.patch(n, 1, [&](int j, int k) { return Vec3(x(n), y(j), z(k)); }, [](const Vec3&) { return Vec3(1, 0, 0); }, "side");
  return b.finish("shapes::slab");
}

Mesh cylindrical_shell(double r_in, double r_out, double span_deg, double width, int n_around, int n_width) {
  require(r_in > 0 && r_out > r_in && width > 0 && span_deg > 0 && span_deg <= 360 && n_around >= 3 && n_width >= 1,
          "cylindrical_shell needs 0 < r_in < r_out, width > 0, 0 < span_deg <= 360, n_around >= 3, n_width >= 1");
  const bool closed = span_deg >= 360;
  const double half = span_deg * std::numbers::pi / 360.0;
  auto theta = [&](int i) { return closed ? -half + 2 * half * static_cast<double>(i % n_around) / n_around
                                          : lerp(-half, half, i, n_around); };
  auto y = [&](int k) { return lerp(-width / 2, width / 2, k, n_width); };
  auto point = [&](double r, int i, double yy) {
    const double t = theta(i);
    return Vec3(r * std::sin(t), yy, r * std::cos(t));
  };
  auto radial = [](const Vec3& p) { return Vec3(p.x(), 0, p.z()); };
  Builder b;
  b.patch(n_around, n_width, [&](int i, int k) { return point(r_in, i, y(k)); }, [&](const Vec3& p) { return Vec3(-radial(p)); }, "contact");
  b.patch(n_around, n_width, [&](int i, int k) { return point(r_out, i, y(k)); }, radial, "outer");
  for (int side = 0; side < 2; ++side) {
    const int k = side ? n_width : 0;
    b.patch(n_around, 1, [&](int i, int j) { return point(j ? r_out : r_in, i, y(k)); },
            [&](const Vec3&) { return Vec3(0, side ? 1 : -1, 0); }, "side");
  }
  if (!closed)
    for (int end = 0; end < 2; ++end) {
      const int i = end ? n_around : 0;
      const double t = theta(i);
      const Vec3 out = end ? Vec3(std::cos(t), 0, -std::sin(t)) : Vec3(-std::cos(t), 0, std::sin(t));
      b.patch(1, n_width, [&](int j, int k) { return point(j ? r_out : r_in, i, y(k)); },
              [&](const Vec3&) { return out; }, "side");
    }
  return b.finish("shapes::cylindrical_shell");
}

Mesh spherical_shell(double r_in, double r_out, double cap_deg, int n_rings, int n_around) {
  require(r_in > 0 && r_out > r_in && cap_deg > 0 && cap_deg < 90 && n_rings >= 1 && n_around >= 3,
          "spherical_shell needs 0 < r_in < r_out, 0 < cap_deg < 90, n_rings >= 1, n_around >= 3");
  const double cap = cap_deg * std::numbers::pi / 180.0;
  auto phi = [&](int j) { return lerp(0.0, cap, j, n_rings); };
  auto psi = [&](int i) { return 2 * std::numbers::pi * static_cast<double>(i % n_around) / n_around; };
  auto point = [&](double r, int i, int j) {
    const double f = phi(j), s = psi(i);
    return Vec3(r * std::sin(f) * std::cos(s), r * std::sin(f) * std::sin(s), r * std::cos(f));
  };
  Builder b;
  b.patch(n_around, n_rings, [&](int i, int j) { return point(r_in, i, j); }, [](const Vec3& p) { return Vec3(-p); }, "contact");
  b.patch(n_around, n_rings, [&](int i, int j) { return point(r_out, i, j); }, [](const Vec3& p) { return p; }, "outer");
  b.patch(n_around, 1, [&](int i, int k) { return point(k ? r_out : r_in, i, n_rings); },
          [&](const Vec3& p) {
            const double s = std::atan2(p.y(), p.x());
            return Vec3(std::cos(cap) * std::cos(s), std::cos(cap) * std::sin(s), -std::sin(cap));
          }, "side");
  return b.finish("shapes::spherical_shell");
}

Mesh bump_plate(double sx, double sy, double thickness, int n, int bumps, double bump_height, unsigned seed) {
  require(sx > 0 && sy > 0 && thickness > 0 && n >= 1 && bumps >= 0 && bump_height >= 0 && std::isfinite(bump_height),
          "bump_plate needs positive sizes, n >= 1, bumps >= 0, finite bump_height >= 0");
  struct Bump {
    double cx, cy, a, inv2s2;
  };
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Bump> field;
  for (int k = 0; k < bumps; ++k) {
    const double cx = (unit(rng) - 0.5) * sx, cy = (unit(rng) - 0.5) * sy;
    const double a = (0.4 + 0.6 * unit(rng)) * bump_height;
    const double s = (0.08 + 0.08 * unit(rng)) * std::min(sx, sy);
    field.push_back({cx, cy, a, 1.0 / (2 * s * s)});
  }
  auto top = [&](double x, double y) {
    double z = thickness;
    for (const Bump& b : field) z += b.a * std::exp(-((x - b.cx) * (x - b.cx) + (y - b.cy) * (y - b.cy)) * b.inv2s2);
    return z;
  };
  auto x = [&](int i) { return lerp(-sx / 2, sx / 2, i, n); };
  auto y = [&](int j) { return lerp(-sy / 2, sy / 2, j, n); };
  Builder b;
  b.patch(n, n, [&](int i, int j) { return Vec3(x(i), y(j), 0.0); }, [](const Vec3&) { return Vec3(0, 0, -1); }, "contact");
  b.patch(n, n, [&](int i, int j) { return Vec3(x(i), y(j), top(x(i), y(j))); }, [](const Vec3&) { return Vec3(0, 0, 1); }, "outer");
  auto wall = [&](double xx, double yy, int k) { return Vec3(xx, yy, k ? top(xx, yy) : 0.0); };
  b.patch(n, 1, [&](int i, int k) { return wall(x(i), y(0), k); }, [](const Vec3&) { return Vec3(0, -1, 0); }, "side");
  b.patch(n, 1, [&](int i, int k) { return wall(x(i), y(n), k); }, [](const Vec3&) { return Vec3(0, 1, 0); }, "side");
  b.patch(n, 1, [&](int j, int k) { return wall(x(0), y(j), k); }, [](const Vec3&) { return Vec3(-1, 0, 0); }, "side");
  b.patch(n, 1, [&](int j, int k) { return wall(x(n), y(j), k); }, [](const Vec3&) { return Vec3(1, 0, 0); }, "side");
  return b.finish("shapes::bump_plate");
}

namespace {

// A sum of plane waves a_k cos(f_k·p + phase_k) with its gradient.
struct Waves {
  struct Wave {
    double fx, fy, phase, a;
  };
  std::vector<Wave> waves;
  Waves(std::mt19937& rng, int count, double size, double amplitude) {
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int k = 0; k < count; ++k) {
      const double lambda = (0.4 + 0.8 * unit(rng)) * size, dir = 2 * std::numbers::pi * unit(rng);
      const double f = 2 * std::numbers::pi / lambda;
      waves.push_back({f * std::cos(dir), f * std::sin(dir), 2 * std::numbers::pi * unit(rng),
                       (0.3 + 0.7 * unit(rng)) * amplitude});
    }
  }
  double at(double x, double y) const {
    double z = 0;
    for (const Wave& w : waves) z += w.a * std::cos(w.fx * x + w.fy * y + w.phase);
    return z;
  }
  Vec2 gradient(double x, double y) const {
    Vec2 g = Vec2::Zero();
    for (const Wave& w : waves) g -= w.a * std::sin(w.fx * x + w.fy * y + w.phase) * Vec2(w.fx, w.fy);
    return g;
  }
  double bound() const {
    double s = 0;
    for (const Wave& w : waves) s += w.a;
    return s;
  }
};

}  // namespace

const char* to_string(Freeform kind) { return kind == Freeform::shell ? "shell" : "height_field"; }

Mesh random_freeform(Freeform kind, unsigned seed, int n) {
  require(n >= 1, "random_freeform needs n >= 1");
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double sx = 40, sy = 25 + 15 * unit(rng), thickness = 2.5;
  const bool shell = kind == Freeform::shell;
  double k1 = 0, k2 = 0, rot = 0;
  if (shell) {
    k1 = (1.0 / 80 + (1.0 / 25 - 1.0 / 80) * unit(rng)) * (unit(rng) < 0.5 ? -1 : 1);
    k2 = (1.0 / 80 + (1.0 / 25 - 1.0 / 80) * unit(rng)) * (unit(rng) < 0.5 ? -1 : 1);
    rot = std::numbers::pi * unit(rng);
  }
  const Waves waves(rng, 6, sx, shell ? 0.1 : 0.5);
  const Waves thick(rng, 4, sx, 1.0);
  const double thick_bound = thick.bound();
  const double c = std::cos(rot), s = std::sin(rot);
  auto h = [&](double x, double y) {
    const double u = c * x + s * y, v = -s * x + c * y;
    return 0.5 * (k1 * u * u + k2 * v * v) + waves.at(x, y);
  };
  auto normal = [&](double x, double y) {  // unit, upwards
    const double u = c * x + s * y, v = -s * x + c * y;
    const double du = k1 * u, dv = k2 * v;
    const Vec2 g = Vec2(c * du - s * dv, s * du + c * dv) + waves.gradient(x, y);
    return Vec3(-g.x(), -g.y(), 1.0).normalized();
  };
  auto t = [&](double x, double y) { return thickness * (1 + 0.25 * thick.at(x, y) / thick_bound); };
  auto x = [&](int i) { return lerp(-sx / 2, sx / 2, i, n); };
  auto y = [&](int j) { return lerp(-sy / 2, sy / 2, j, n); };
  auto contact = [&](int i, int j) { return Vec3(x(i), y(j), h(x(i), y(j))); };
  auto outer = [&](int i, int j) {
    const double xi = x(i), yj = y(j);
    if (!shell) return Vec3(xi, yj, h(xi, yj) + t(xi, yj));
    return Vec3(Vec3(xi, yj, h(xi, yj)) + t(xi, yj) * normal(xi, yj));
  };
  Builder b;
  b.patch(n, n, contact, [&](const Vec3& p) { return Vec3(-normal(p.x(), p.y())); }, "contact");
  b.patch(n, n, outer, [&](const Vec3& p) { return normal(p.x(), p.y()); }, "outer");
  auto wall = [&](int i, int j, int k) { return k ? outer(i, j) : contact(i, j); };
  b.patch(n, 1, [&](int i, int k) { return wall(i, 0, k); }, [](const Vec3&) { return Vec3(0, -1, 0); }, "side");
  b.patch(n, 1, [&](int i, int k) { return wall(i, n, k); }, [](const Vec3&) { return Vec3(0, 1, 0); }, "side");
  b.patch(n, 1, [&](int j, int k) { return wall(0, j, k); }, [](const Vec3&) { return Vec3(-1, 0, 0); }, "side");
  b.patch(n, 1, [&](int j, int k) { return wall(n, j, k); }, [](const Vec3&) { return Vec3(1, 0, 0); }, "side");
  return b.finish(std::string("shapes::random_freeform(") + to_string(kind) + ", " + std::to_string(seed) + ")");
}

}  // namespace clearfit::shapes
