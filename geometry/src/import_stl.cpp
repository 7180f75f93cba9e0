// STL, ASCII and binary. Read here rather than through OpenMesh: OpenMesh's STL
// reader drops triangles whose corners coincide (breaking the file's face order),
// welds a nan vertex into an arbitrary other vertex, and reads "nan" in ASCII as
// a silent stream failure. The format is a 50-byte record or a 7-line block per
// triangle; the checks below name the facet and line of any fault.
#include "import_internal.hpp"

#include <bit>
#include <cctype>
#include <cmath>
#include <fstream>
#include <cstdint>
#include <cstring>
#include <map>

namespace clearfit::detail {
namespace {

static_assert(std::endian::native == std::endian::little, "binary STL reading assumes a little-endian machine");

// Welds exactly equal positions (the STL has one vertex record per corner).
struct Welder {
  RawMesh& raw;
  std::map<std::array<double, 3>, int> index;
  int corners = 0;
  int add(const Vec3& p) {
    ++corners;
    auto [it, inserted] = index.try_emplace({p.x() + 0.0, p.y() + 0.0, p.z() + 0.0},
                                            static_cast<int>(raw.vertices.size()));
    if (inserted) raw.vertices.push_back(p);
    return it->second;
  }
};

void check_finite(const Vec3& p, const std::string& name, const std::string& where) {
  if (!p.allFinite())
    throw InputError(name, where, "coordinate is not finite (nan or inf)", "fix or re-export the mesh");
}

RawMesh read_binary(const std::string& bytes, const std::string& name, std::uint64_t count) {
  RawMesh raw;
  raw.polygons.reserve(count);
  Welder weld{raw, {}};
  for (std::uint64_t t = 0; t < count; ++t) {
    const char* rec = bytes.data() + 84 + 50 * t;
    std::vector<int> tri(3);
    for (int k = 0; k < 3; ++k) {
      float xyz[3];
      std::memcpy(xyz, rec + 12 * (k + 1), sizeof xyz);
      const Vec3 p(xyz[0], xyz[1], xyz[2]);
      check_finite(p, name, "facet " + std::to_string(t) + ", vertex " + std::to_string(k));
      tri[k] = weld.add(p);
    }
    raw.polygons.push_back(std::move(tri));
  }
  if (weld.corners > static_cast<int>(raw.vertices.size()))
    raw.notes.push_back("merged " + std::to_string(weld.corners) + " STL corners into " +
                        std::to_string(raw.vertices.size()) + " vertices (exactly equal positions)");
  return raw;
}

RawMesh read_ascii(const std::string& text, const std::string& name, bool may_be_binary) {
  RawMesh raw;
  Welder weld{raw, {}};
  std::vector<int> facet;
  bool in_facet = false;
  int line_no = 0;
  auto fail = [&](const std::string& problem) -> void {
    throw InputError(name, "line " + std::to_string(line_no), problem,
                     may_be_binary ? "if this is a binary STL, its triangle count does not match the file size"
                                   : "export the mesh again");
  };
  LineCursor lines(text);
  for (std::string_view line; lines.next(line);) {
    line_no = lines.line_no();
    const auto tok = split_ws(line);
    if (tok.empty()) continue;
    const std::string_view key = tok[0];
    if (key == "solid" || key == "endsolid" || key == "outer" || key == "endloop") continue;
    if (key == "facet") {
      if (in_facet) fail("'facet' before the previous facet's 'endfacet'");
      in_facet = true;
      facet.clear();
    } else if (key == "vertex") {
      if (!in_facet) fail("'vertex' outside a facet");
      const std::string where = "line " + std::to_string(line_no) + " (facet " + std::to_string(raw.polygons.size()) +
                                ", vertex " + std::to_string(facet.size()) + ")";
      if (tok.size() != 4 || facet.size() == 3)
        throw InputError(name, where, "expected 'vertex x y z', three per facet");
      Vec3 p;
      for (int k = 0; k < 3; ++k) {
        double value = 0;
        if (!parse_double(tok[k + 1], value))
          throw InputError(name, where, "'" + std::string(tok[k + 1]) + "' is not a number");
        p[k] = value;
      }
      check_finite(p, name, where);
      facet.push_back(weld.add(p));
    } else if (key == "endfacet") {
      if (!in_facet) fail("'endfacet' without 'facet'");
      if (facet.size() != 3)
        fail("facet " + std::to_string(raw.polygons.size()) + " has " + std::to_string(facet.size()) +
             " vertices; STL facets have 3");
      raw.polygons.push_back(facet);
      in_facet = false;
    } else {
      fail("unexpected '" + std::string(key.substr(0, 40)) + "' in an ASCII STL");
    }
  }
  if (in_facet) fail("the file ends inside a facet (truncated?)");
  if (weld.corners > static_cast<int>(raw.vertices.size()))
    raw.notes.push_back("merged " + std::to_string(weld.corners) + " STL corners into " +
                        std::to_string(raw.vertices.size()) + " vertices (exactly equal positions)");
  return raw;
}

}  // namespace

RawMesh read_stl(const std::filesystem::path& path) {
  const std::string name = display(path);
  const std::uint64_t size = std::filesystem::file_size(path);
  // Binary layout: 80-byte header, uint32 count, then 50 bytes per triangle.
  // Check the size the count implies before reading or allocating anything.
  std::uint32_t count = 0;
  std::string head;
  {
    std::ifstream in(path, std::ios::binary);
    head.resize(std::min<std::uint64_t>(size, 84));
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    if (!in) throw InputError(name, "header", "cannot read the first bytes of the file");
  }
  if (head.size() == 84) std::memcpy(&count, head.data() + 80, 4);
  const std::uint64_t binary_size = 84 + 50ull * count;
  const size_t first = head.find_first_not_of(" \t\r\n");
  const bool starts_solid = first != std::string::npos && head.compare(first, 5, "solid") == 0;
  if (head.size() == 84 && binary_size == size) {
    RawMesh raw = read_binary(read_file_bytes(path), name, count);
    return raw;
  }
  if (starts_solid) return read_ascii(read_file_bytes(path), name, head.size() == 84);
  if (head.size() < 84)
    throw InputError(name, "header", "only " + std::to_string(size) + " bytes: too short for a binary STL (84-byte header) "
                     "and not an ASCII STL (no 'solid')");
  if (binary_size > size)
    throw InputError(name, "header",
                     "the binary STL header claims " + std::to_string(count) + " triangles (" +
                         std::to_string(binary_size) + " bytes) but the file has " + std::to_string(size) +
                         " bytes: truncated or corrupt", "export the mesh again");
  throw InputError(name, "header",
                   "the binary STL header claims " + std::to_string(count) + " triangles (" +
                       std::to_string(binary_size) + " bytes) but the file has " + std::to_string(size - binary_size) +
                       " bytes more", "export the mesh again");
}

}  // namespace clearfit::detail
