// OFF, read here, and the structure of a PLY file, checked before OpenMesh reads it.
// OpenMesh's readers trust their input: a property declared before any element,
// a damaged 'element' line or a negative list length crash them or make them
// allocate without bound. Every count here is checked against what the file can
// hold (one token or one byte per value at least) before anything is allocated,
// so what reaches OpenMesh is a file whose every element and list fits.
// OFF is not handed to OpenMesh at all: its reader takes the header from the
// file's first line only and then reads the counts with `>>` into variables it
// never initialised, so an OFF whose first line is blank or a comment made it
// add faces without bound (found by fuzz_off); a face colour after the indices
// is read as the next face's length. The OFF checks below read the mesh as they go.
#include "import_internal.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <map>

namespace clearfit::detail {
namespace {

std::uint64_t parse_count(std::string_view t, const std::string& name, const std::string& where) {
  std::uint64_t n = 0;
  auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), n);
  if (ec != std::errc() || ptr != t.data() + t.size() || n > 0x7fffffff)
    throw InputError(name, where, "'" + std::string(t.substr(0, 40)) + "' is not a valid element count",
                     "a count is a whole number from 0 to 2147483647");
  return n;
}

// Walks the lines of `text` from `pos`; calls f(line_number, tokens) for lines with tokens
// (comments after '#' removed when `comments`).
template <class F>
void for_lines(const std::string& text, size_t pos, int line_no, bool comments, F&& f) {
  LineCursor lines(text, pos, line_no);
  for (std::string_view line; lines.next(line);) {
    if (comments) line = line.substr(0, line.find('#'));
    auto tok = split_ws(line);
    if (!tok.empty() && !f(lines.line_no(), tok)) return;
  }
}

// A number token: finite, else InputError at `where`.
double finite_number(std::string_view t, const std::string& name, const std::string& where) {
  double v = 0;
  if (!parse_double(t, v)) throw InputError(name, where, "'" + std::string(t.substr(0, 40)) + "' is not a number");
  if (!std::isfinite(v)) throw InputError(name, where, "coordinate is not finite (nan or inf)", "fix or re-export the mesh");
  return v;
}

// ---- OFF -------------------------------------------------------------------

// The OFF body: `nv` vertex lines "x y z [more]", then `nf` face lines "k i1 ... ik [colour]",
// read into `raw` (positions and faces; the rest of a line is ignored).
void read_off_body(const std::string& text, size_t pos, int line_no, const PlyOffCounts& d, const std::string& name,
                   RawMesh& raw) {
  std::uint64_t body_line = 0;
  for_lines(text, pos, line_no, true, [&](int line, const std::vector<std::string_view>& tok) {
    if (body_line >= d.vertices + d.faces) return false;  // trailing lines are ignored
    const bool vertex = body_line < d.vertices;
    const std::uint64_t index = vertex ? body_line : body_line - d.vertices;
    const std::string where = "line " + std::to_string(line) + (vertex ? " (vertex " : " (face ") + std::to_string(index) + ")";
    for (auto t : tok) finite_number(t, name, where);
    if (vertex && tok.size() < 3) throw InputError(name, where, "a vertex line needs x y z", "fix or re-export the mesh");
    if (vertex) {
      raw.vertices.emplace_back(finite_number(tok[0], name, where), finite_number(tok[1], name, where),
                                finite_number(tok[2], name, where));
    } else {
      std::int64_t k = -1;
      auto [ptr, ec] = std::from_chars(tok[0].data(), tok[0].data() + tok[0].size(), k);
      if (ec != std::errc() || ptr != tok[0].data() + tok[0].size() || k < 0 || static_cast<std::uint64_t>(k) + 1 > tok.size())
        throw InputError(name, where,
                         "a face line is 'k i1 ... ik' with k its number of vertices; found '" + std::string(tok[0].substr(0, 40)) +
                             "' and " + std::to_string(tok.size() - 1) + " indices",
                         "fix or re-export the mesh");
      std::vector<int> poly(static_cast<size_t>(k));
      for (std::int64_t i = 0; i < k; ++i) {
        const std::string_view t = tok[static_cast<size_t>(i) + 1];
        auto [end, err] = std::from_chars(t.data(), t.data() + t.size(), poly[static_cast<size_t>(i)]);
        if (err != std::errc() || end != t.data() + t.size())
          throw InputError(name, where, "'" + std::string(t.substr(0, 40)) + "' is not a vertex index",
                           "vertex indices are whole numbers from 0, one per vertex of the face");
      }
      raw.polygons.push_back(std::move(poly));
    }
    ++body_line;
    return true;
  });
  if (body_line < d.vertices + d.faces)
    throw InputError(name, "", "declares " + std::to_string(d.vertices) + " vertices and " + std::to_string(d.faces) +
                                   " faces but holds only " + std::to_string(body_line) + " lines of them (truncated?)");
}

// ---- PLY -------------------------------------------------------------------

enum class PlyFormat { ascii, little, big };

struct PlyProperty {
  std::string name;
  int size = 0;        // bytes of the value (binary)
  int count_size = 0;  // list: bytes of the count; 0 for a scalar
  bool count_signed = false;
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> properties;
  int line = 0;
};

// Size in bytes of a PLY type name; 0 if unknown. `is_signed`/`integral` describe it.
int ply_type_size(std::string_view t, bool* is_signed = nullptr, bool* integral = nullptr) {
  static const std::map<std::string_view, std::array<int, 3>> types = {
      {"char", {1, 1, 1}},   {"int8", {1, 1, 1}},   {"uchar", {1, 0, 1}},   {"uint8", {1, 0, 1}},
      {"short", {2, 1, 1}},  {"int16", {2, 1, 1}},  {"ushort", {2, 0, 1}},  {"uint16", {2, 0, 1}},
      {"int", {4, 1, 1}},    {"int32", {4, 1, 1}},  {"uint", {4, 0, 1}},    {"uint32", {4, 0, 1}},
      {"float", {4, 1, 0}},  {"float32", {4, 1, 0}}, {"double", {8, 1, 0}}, {"float64", {8, 1, 0}}};
  const auto it = types.find(t);
  if (it == types.end()) return 0;
  if (is_signed) *is_signed = it->second[1];
  if (integral) *integral = it->second[2];
  return it->second[0];
}

struct PlyHeader {
  PlyFormat format = PlyFormat::ascii;
  std::vector<PlyElement> elements;
  size_t body = 0;  // offset of the first byte after end_header
  int body_line = 0;
};

PlyProperty parse_property(const std::vector<std::string_view>& tok, const std::string& name, const std::string& where) {
  const std::string hint = "a property line is 'property TYPE NAME' or 'property list COUNT_TYPE TYPE NAME'";
  PlyProperty p;
  if (tok.size() == 3 && (p.size = ply_type_size(tok[1])) > 0) {
    p.name = std::string(tok[2]);
    return p;
  }
  bool integral = false;
  if (tok.size() == 5 && tok[1] == "list" && (p.count_size = ply_type_size(tok[2], &p.count_signed, &integral)) > 0 && integral &&
      (p.size = ply_type_size(tok[3])) > 0) {
    p.name = std::string(tok[4]);
    return p;
  }
  throw InputError(name, where, "damaged property line", hint);
}

PlyHeader parse_ply_header(const std::string& text, const std::string& name) {
  PlyHeader h;
  LineCursor lines(text);
  bool ended = false, has_format = false;
  for (std::string_view line; !ended && lines.next(line);) {
    const int line_no = lines.line_no();
    const auto tok = split_ws(line);
    const std::string where = "line " + std::to_string(line_no);
    if (line_no == 1) {
      if (tok.size() != 1 || tok[0] != "ply") throw InputError(name, where, "a PLY file starts with 'ply'");
      continue;
    }
    if (tok.empty() || tok[0] == "comment" || tok[0] == "obj_info") continue;
    if (tok[0] == "format") {
      if (has_format) throw InputError(name, where, "a second 'format' line");
      if (tok.size() != 3 || tok[2] != "1.0" || (tok[1] != "ascii" && tok[1] != "binary_little_endian" && tok[1] != "binary_big_endian"))
        throw InputError(name, where, "damaged format line", "'format ascii 1.0', 'format binary_little_endian 1.0' or 'format binary_big_endian 1.0'");
      h.format = tok[1] == "ascii" ? PlyFormat::ascii : tok[1] == "binary_little_endian" ? PlyFormat::little : PlyFormat::big;
      has_format = true;
    } else if (tok[0] == "element") {
      if (tok.size() != 3) throw InputError(name, where, "damaged element line", "an element line is 'element NAME COUNT'");
      for (const auto& e : h.elements)
        if (e.name == tok[1]) throw InputError(name, where, "element '" + std::string(tok[1]) + "' is declared twice");
      h.elements.push_back({std::string(tok[1]), parse_count(tok[2], name, where), {}, line_no});
    } else if (tok[0] == "property") {
      if (h.elements.empty()) throw InputError(name, where, "a property before any element", "declare 'element NAME COUNT' first");
      h.elements.back().properties.push_back(parse_property(tok, name, where));
    } else if (tok[0] == "end_header") {
      if (tok.size() != 1) throw InputError(name, where, "damaged end_header line");
      ended = true;
    } else {
      throw InputError(name, where, "unknown header line '" + std::string(tok[0].substr(0, 40)) + "'",
                       "a PLY header has only format, comment, obj_info, element and property lines");
    }
  }
  if (!ended) throw InputError(name, "header", "no 'end_header' line");
  if (!has_format) throw InputError(name, "header", "no 'format' line");
  for (const auto& e : h.elements) {
    const std::string where = "line " + std::to_string(e.line);
    if (e.count > 0 && e.properties.empty()) throw InputError(name, where, "element '" + e.name + "' has no properties");
    if (e.name == "vertex") {
      int xyz = 0;
      for (const auto& p : e.properties) xyz += (p.name == "x" || p.name == "y" || p.name == "z") && p.count_size == 0;
      if (xyz != 3) throw InputError(name, where, "element 'vertex' lacks the scalar properties x, y and z");
    }
  }
  h.body = lines.pos();
  h.body_line = lines.line_no();
  return h;
}

[[noreturn]] void truncated(const std::string& name, const PlyElement& e, std::uint64_t item) {
  throw InputError(name, "", "declares " + std::to_string(e.count) + " of element '" + e.name + "' but ends in number " +
                                 std::to_string(item) + " (truncated?)");
}

// ASCII body: every token a finite number, each list's length a whole number the file holds.
void check_ply_ascii(const std::string& text, const PlyHeader& h, const std::string& name) {
  LineCursor lines(text, h.body, h.body_line);
  std::vector<std::string_view> tok;
  size_t next = 0;
  std::string_view line;
  auto token = [&](std::string_view& t) {
    while (next >= tok.size()) {
      if (!lines.next(line)) return false;
      tok = split_ws(line);
      next = 0;
    }
    t = tok[next++];
    return true;
  };
  for (const auto& e : h.elements)
    for (std::uint64_t i = 0; i < e.count; ++i)
      for (const auto& p : e.properties) {
        std::string_view t;
        auto where = [&] { return "line " + std::to_string(lines.line_no()) + " (" + e.name + " " + std::to_string(i) + ")"; };
        if (!token(t)) truncated(name, e, i);
        if (p.count_size == 0) {
          finite_number(t, name, where());
          continue;
        }
        std::int64_t n = -1;
        auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), n);
        if (ec != std::errc() || ptr != t.data() + t.size() || n < 0)
          throw InputError(name, where(), "the length of list '" + p.name + "' is '" + std::string(t.substr(0, 40)) + "'",
                           "a list starts with its number of values, a whole number >= 0");
        for (std::int64_t k = 0; k < n; ++k) {
          if (!token(t)) truncated(name, e, i);
          finite_number(t, name, where());
        }
      }
}

// Binary body: each list's length read as its type, bounded by the bytes left.
void check_ply_binary(const std::string& text, const PlyHeader& h, const std::string& name) {
  const std::uint64_t end = text.size();
  std::uint64_t at = h.body;
  const bool swap = (h.format == PlyFormat::big) != (std::endian::native == std::endian::big);
  for (const auto& e : h.elements) {
    bool lists = false;
    std::uint64_t row = 0;
    for (const auto& p : e.properties) {
      lists = lists || p.count_size > 0;
      row += p.count_size > 0 ? p.count_size : p.size;
    }
    if (!lists) {  // fixed rows: one multiplication
      if (e.count * row > end - at) truncated(name, e, (end - at) / row);
      at += e.count * row;
      continue;
    }
    for (std::uint64_t i = 0; i < e.count; ++i)
      for (const auto& p : e.properties) {
        if (p.count_size == 0) {
          if (static_cast<std::uint64_t>(p.size) > end - at) truncated(name, e, i);
          at += p.size;
          continue;
        }
        if (static_cast<std::uint64_t>(p.count_size) > end - at) truncated(name, e, i);
        unsigned char b[4] = {};
        std::memcpy(b, text.data() + at, p.count_size);
        if (swap) std::reverse(b, b + p.count_size);
        std::int64_t n = 0;
        if (p.count_size == 1) n = p.count_signed ? static_cast<std::int8_t>(b[0]) : b[0];
        else if (p.count_size == 2) {
          std::uint16_t v;
          std::memcpy(&v, b, 2);
          n = p.count_signed ? static_cast<std::int16_t>(v) : v;
        } else {
          std::uint32_t v;
          std::memcpy(&v, b, 4);
          if (p.count_signed) n = static_cast<std::int32_t>(v);  // (a ?: of int32 and uint32 would be unsigned)
          else n = v;
        }
        at += p.count_size;
        if (n < 0)
          throw InputError(name, e.name + " " + std::to_string(i), "the length of list '" + p.name + "' is " + std::to_string(n),
                           "a list starts with its number of values, a whole number >= 0");
        if (static_cast<std::uint64_t>(n) * p.size > end - at) truncated(name, e, i);
        at += static_cast<std::uint64_t>(n) * p.size;
      }
  }
}

}  // namespace

RawMesh read_off(const std::filesystem::path& path) {
  const std::string name = display(path);
  const std::string text = read_file_bytes(path);
  PlyOffCounts d;
  std::vector<std::string_view> head;
  LineCursor lines(text);
  bool binary = false;
  // Header: "[ST][C][N][4][n]OFF [BINARY]", then the three counts (possibly on the same line).
  for (std::string_view line; head.size() < 4 && lines.next(line);) {
    const int line_no = lines.line_no();
    for (auto t : split_ws(line.substr(0, line.find('#')))) {
      if (head.empty() && (t.size() < 3 || t.substr(t.size() - 3) != "OFF"))
        throw InputError(name, "line " + std::to_string(line_no), "an OFF file starts with 'OFF'");
      if (t == "BINARY") binary = true;
      else if (head.size() < 4) head.push_back(t);
    }
  }
  if (head.size() < 4) throw InputError(name, "header", "missing the vertex, face and edge counts");
  d.vertices = parse_count(head[1], name, "header");
  d.faces = parse_count(head[2], name, "header");
  parse_count(head[3], name, "header");
  if (head[0].find("4") != std::string_view::npos || head[0].find("n") != std::string_view::npos || binary)
    throw InputError(name, "line 1", "the " + std::string(head[0].substr(0, 20)) + (binary ? " BINARY" : "") + " variant of OFF is not supported",
                     "save the mesh as plain 3D ASCII OFF, PLY or STL");
  // Counts on the header's last line end the header: the body starts on the next line.
  RawMesh raw;
  read_off_body(text, lines.pos(), lines.line_no(), d, name, raw);
  return raw;
}

PlyOffCounts check_ply(const std::string& text, const std::string& name) {
  const PlyHeader h = parse_ply_header(text, name);
  if (h.format == PlyFormat::ascii) check_ply_ascii(text, h, name);
  else check_ply_binary(text, h, name);
  PlyOffCounts d;
  for (const auto& e : h.elements) {
    if (e.name == "vertex") d.vertices = e.count;
    if (e.name == "face") d.faces = e.count;
  }
  return d;
}

}  // namespace clearfit::detail
