#pragma once
// Small independent checks on meshes for the tests (no clearfit code involved
// beyond the Mesh struct): edge-use counts, closedness, orientation.
#include <clearfit/geometry/mesh.hpp>
#include <map>

namespace clearfit::test {

/// True if every directed edge appears exactly once and its reverse exactly
/// once: a closed, consistently oriented 2-manifold.
inline bool closed_and_consistent(const Mesh& m) {
  std::map<std::pair<int, int>, int> directed;
  for (const auto& f : m.faces)
    for (int k = 0; k < 3; ++k) ++directed[{f[k], f[(k + 1) % 3]}];
  for (const auto& [e, n] : directed) {
    if (n != 1) return false;
    auto it = directed.find({e.second, e.first});
    if (it == directed.end() || it->second != 1) return false;
  }
  return true;
}

}  // namespace clearfit::test
