#pragma once
// Reading clearfit's heatmap .glb files back in tests, through tinygltf alone
// (independent of the reports module's own reader), and base64 as RFC 4648 says.
#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace clearfit::test {

/// The binary glTF `bytes`; a test failure when tinygltf cannot read them cleanly.
inline tinygltf::Model parse_glb(const std::string& bytes) {
  tinygltf::Model model;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  EXPECT_TRUE(loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                          static_cast<unsigned int>(bytes.size())))
      << err;
  EXPECT_EQ(err, "");
  return model;
}

/// The binary glTF at `path`, as parse_glb.
inline tinygltf::Model load_glb(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << "cannot open " << path;
  return parse_glb(std::string(std::istreambuf_iterator<char>(in), {}));
}

/// Accessor `accessor` as `components` values of type T per element (byteStride honoured).
template <typename T>
std::vector<T> read_accessor(const tinygltf::Model& m, int accessor, int components) {
  const tinygltf::Accessor& acc = m.accessors.at(accessor);
  const tinygltf::BufferView& view = m.bufferViews.at(acc.bufferView);
  const unsigned char* p = m.buffers.at(view.buffer).data.data() + view.byteOffset + acc.byteOffset;
  const std::size_t element = components * sizeof(T), stride = view.byteStride ? view.byteStride : element;
  std::vector<T> out(acc.count * components);
  for (std::size_t i = 0; i < acc.count; ++i) std::memcpy(&out[i * components], p + i * stride, element);
  return out;
}

/// The attribute `name` (`components` floats per vertex) of the heatmap's vertex-coloured mesh
/// ("heatmap_vertex_colors", whose primitives share one vertex set); empty when the mesh has no such attribute.
inline std::vector<float> heatmap_attribute(const tinygltf::Model& m, const std::string& name, int components = 1) {
  for (const tinygltf::Mesh& mesh : m.meshes) {
    if (mesh.name != "heatmap_vertex_colors" || mesh.primitives.empty()) continue;
    const auto& attributes = mesh.primitives.front().attributes;
    const auto it = attributes.find(name);
    return it == attributes.end() ? std::vector<float>{} : read_accessor<float>(m, it->second, components);
  }
  ADD_FAILURE() << "the model has no mesh 'heatmap_vertex_colors'";
  return {};
}

/// `text` decoded from base64 (RFC 4648 §4, padding optional); a test failure on any other character.
inline std::string base64_decode(const std::string& text) {
  static const std::string alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::uint32_t bits = 0;
  int count = 0;
  for (char c : text) {
    if (c == '=') break;
    const std::size_t v = alphabet.find(c);
    if (v == std::string::npos) {
      ADD_FAILURE() << "not base64: '" << c << "'";
      return out;
    }
    bits = (bits << 6) | static_cast<std::uint32_t>(v), count += 6;
    if (count >= 8) count -= 8, out += static_cast<char>((bits >> count) & 0xFF);
  }
  return out;
}

/// The glb embedded in report.html for view `key` (base64 in <script class="clearfit-model" data-view=key>); empty when
/// the page has no such view.
inline std::string embedded_glb(const std::string& html, const std::string& key) {
  const std::string open = "class=\"clearfit-model\" data-view=\"" + key + "\">";
  const std::size_t a = html.find(open);
  if (a == std::string::npos) return {};
  const std::size_t b = html.find("</script>", a);
  return base64_decode(html.substr(a + open.size(), b - a - open.size()));
}

}  // namespace clearfit::test
