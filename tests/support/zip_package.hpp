#pragma once
// A zip package written byte by byte from the format's description (PKWARE
// APPNOTE 4.3: local headers, central directory, end record), independent of
// libzip and lib3mf, so a test can state in its headers sizes that lie. Each
// entry is stored (method 0) or deflated (method 8) as one deflate block of
// kind 00 ("no compression", RFC 1951 3.2.4), so no compressor is needed.
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace clearfit::test {

struct ZipEntry {
  std::string name;
  std::string data;                      ///< what the entry unpacks to
  bool deflate = false;                  ///< method 8 (one stored deflate block) instead of 0
  std::optional<std::uint32_t> declared;  ///< the unpacked size its headers claim (default: the truth)
};

inline std::uint32_t crc32_of(const std::string& s) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (unsigned char b : s) {
    c ^= b;
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return ~c;
}

inline std::string zip_package(const std::vector<ZipEntry>& entries) {
  auto u16 = [](std::string& s, std::uint32_t v) { s += char(v & 0xFF), s += char((v >> 8) & 0xFF); };
  auto u32 = [&](std::string& s, std::uint32_t v) { u16(s, v & 0xFFFF), u16(s, v >> 16); };
  std::string out, central;
  for (const ZipEntry& e : entries) {
    std::string packed = e.data;
    if (e.deflate) {  // one final block of kind 00: BFINAL 1, BTYPE 00, then LEN and its complement (data < 64 KiB)
      const auto n = static_cast<std::uint32_t>(e.data.size());
      packed = std::string(1, '\x01');
      u16(packed, n), u16(packed, ~n & 0xFFFF);
      packed += e.data;
    }
    const std::uint32_t offset = static_cast<std::uint32_t>(out.size());
    auto common = [&](std::string& s) {  // version needed .. name length (APPNOTE 4.3.7 / 4.3.12)
      u16(s, 20), u16(s, 0), u16(s, e.deflate ? 8 : 0), u16(s, 0), u16(s, 0x21);
      u32(s, crc32_of(e.data)), u32(s, static_cast<std::uint32_t>(packed.size()));
      u32(s, e.declared.value_or(static_cast<std::uint32_t>(e.data.size()))), u16(s, static_cast<std::uint32_t>(e.name.size()));
    };
    u32(out, 0x04034b50), common(out), u16(out, 0), out += e.name, out += packed;
    u32(central, 0x02014b50), u16(central, 20), common(central);
    u16(central, 0), u16(central, 0), u16(central, 0), u16(central, 0), u32(central, 0), u32(central, offset), central += e.name;
  }
  const auto n = static_cast<std::uint32_t>(entries.size());
  const auto cd_offset = static_cast<std::uint32_t>(out.size()), cd_size = static_cast<std::uint32_t>(central.size());
  out += central;
  u32(out, 0x06054b50), u16(out, 0), u16(out, 0), u16(out, n), u16(out, n), u32(out, cd_size), u32(out, cd_offset), u16(out, 0);
  return out;
}

/// The entries of a 3MF package holding `model_xml` as its model: content types, relationships, the model (last).
inline std::vector<ZipEntry> package_3mf_entries(std::string model_xml) {
  auto entry = [](std::string name, std::string data) { return ZipEntry{std::move(name), std::move(data), false, std::nullopt}; };
  return {
      entry("[Content_Types].xml",
       "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Types xmlns=\"http://schemas.openxmlformats.org/package/2006/content-types\">"
       "<Default Extension=\"rels\" ContentType=\"application/vnd.openxmlformats-package.relationships+xml\"/>"
       "<Default Extension=\"model\" ContentType=\"application/vnd.ms-package.3dmanufacturing-3dmodel+xml\"/></Types>"),
      entry("_rels/.rels",
       "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Relationships xmlns=\"http://schemas.openxmlformats.org/package/2006/relationships\">"
       "<Relationship Target=\"/3D/3dmodel.model\" Id=\"rel0\" Type=\"http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel\"/></Relationships>"),
      entry("3D/3dmodel.model", std::move(model_xml)),
  };
}

/// A 3MF package (stored entries, honest sizes) holding `model_xml` as its model.
inline std::string package_3mf(std::string model_xml) { return zip_package(package_3mf_entries(std::move(model_xml))); }

/// The entries of a 3MF package of a tetrahedron 10 mm high: content types, relationships, the model (last).
inline std::vector<ZipEntry> tetra_3mf_entries() {
  return package_3mf_entries(
       "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<model unit=\"millimeter\" xml:lang=\"en-US\" "
       "xmlns=\"http://schemas.microsoft.com/3dmanufacturing/core/2015/02\"><resources><object id=\"1\" type=\"model\" name=\"contact\">"
       "<mesh><vertices><vertex x=\"0\" y=\"0\" z=\"0\"/><vertex x=\"10\" y=\"0\" z=\"0\"/><vertex x=\"0\" y=\"10\" z=\"0\"/>"
       "<vertex x=\"0\" y=\"0\" z=\"10\"/></vertices><triangles><triangle v1=\"0\" v2=\"2\" v3=\"1\"/><triangle v1=\"0\" v2=\"1\" v3=\"3\"/>"
       "<triangle v1=\"0\" v2=\"3\" v3=\"2\"/><triangle v1=\"1\" v2=\"2\" v3=\"3\"/></triangles></mesh></object></resources>"
       "<build><item objectid=\"1\"/></build></model>");
}

/// The tetrahedron's 3MF with its model entry (the last) deflated or not and claiming `declared` bytes.
inline std::string tetra_3mf(bool deflate = false, std::optional<std::uint32_t> declared = std::nullopt) {
  auto entries = tetra_3mf_entries();
  entries.back().deflate = deflate;
  entries.back().declared = declared;
  return zip_package(entries);
}

}  // namespace clearfit::test
