// The 3D view's triangle budget: the heatmap's vertex-coloured mesh simplified
// (clearfit/reports/simplify.hpp), then the glTF model rewritten around the
// vertices still used (see report_view.hpp).
#include "report_view.hpp"

#include <clearfit/error.hpp>

#include <algorithm>
#include <cstring>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>

namespace clearfit::reports::detail {

std::optional<HeatmapGlb> simplify_heatmap_for_view(const HeatmapGlb& g, std::size_t max_triangles) {
  if (g.triangles.size() / 3 <= max_triangles) return g;
  const tinygltf::Model& m = g.model;
  const std::vector<tinygltf::Primitive>& prims = m.meshes.at(g.mesh).primitives;
  const int position = prims.at(0).attributes.at("POSITION");
  const std::size_t nv = g.vertex_count();

  // The index accessors of g's primitives and where their triangles start in g.triangles.
  std::map<int, std::size_t> prim_of_indices;
  std::vector<std::size_t> first_face{0};
  for (std::size_t p = 0; p < prims.size(); ++p) {
    prim_of_indices[prims[p].indices] = p;
    first_face.push_back(first_face.back() + m.accessors.at(prims[p].indices).count / 3);
  }
  // Vertex accessors: every attribute of a primitive (of any mesh) on g's vertex set.
  std::vector<char> is_vertex_attribute(m.accessors.size(), 0);
  for (const tinygltf::Mesh& mesh : m.meshes)
    for (const tinygltf::Primitive& p : mesh.primitives) {
      const auto pos = p.attributes.find("POSITION");
      if (pos == p.attributes.end() || pos->second != position) continue;
      if (!prim_of_indices.count(p.indices) || !p.targets.empty()) return std::nullopt;
      for (const auto& [name, accessor] : p.attributes) {
        if (m.accessors.at(accessor).count != nv) return std::nullopt;
        is_vertex_attribute.at(accessor) = 1;
      }
    }
  for (const tinygltf::Accessor& a : m.accessors)
    if (a.sparse.isSparse) return std::nullopt;

  std::vector<float> colour;
  int colour_components = 3;
  if (const auto c = prims[0].attributes.find("COLOR_0"); c != prims[0].attributes.end()) {
    const tinygltf::Accessor& acc = m.accessors.at(c->second);
    colour_components = tinygltf::GetNumComponentsInType(acc.type);
    if (acc.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT &&
        (colour_components == 3 || colour_components == 4))
      colour = read_floats(m, c->second, colour_components, "heatmap.glb");
  }
  const SimplifiedTriangles s =
      simplify_triangles(g.position_mm, g.triangles, max_triangles, colour, colour_components);

  // Each primitive keeps its own triangles; vertices renumbered in their old order.
  std::vector<std::vector<std::uint32_t>> prim_triangles(prims.size());
  std::vector<std::uint32_t> new_index(nv, std::numeric_limits<std::uint32_t>::max());
  for (std::size_t t = 0; t < s.source_face.size(); ++t) {
    const std::size_t p =
        std::upper_bound(first_face.begin(), first_face.end(), s.source_face[t]) - first_face.begin() - 1;
    prim_triangles.at(p).insert(prim_triangles[p].end(), &s.triangles[3 * t], &s.triangles[3 * t] + 3);
    for (int k = 0; k < 3; ++k) new_index[s.triangles[3 * t + k]] = 0;
  }
  std::vector<std::uint32_t> kept;
  for (std::size_t v = 0; v < nv; ++v)
    if (new_index[v] == 0) {
      new_index[v] = static_cast<std::uint32_t>(kept.size());
      kept.push_back(static_cast<std::uint32_t>(v));
    }
  for (auto& tris : prim_triangles) {
    if (tris.empty()) return std::nullopt;  // glTF accessors cannot be empty
    for (std::uint32_t& i : tris) i = new_index[i];
  }

  // One new buffer: rewritten vertex and index accessors, the other views (images, ...) copied.
  HeatmapGlb r;
  r.model = m;
  r.info = g.info;
  r.mesh = g.mesh;
  std::vector<unsigned char> data;
  std::vector<tinygltf::BufferView> views;
  auto add_view = [&](const unsigned char* bytes, std::size_t n, int target, int stride, const std::string& name) {
    return append_buffer_view(data, views, bytes, n, target, stride, name);
  };
  std::vector<int> view_map(m.bufferViews.size(), -1);
  auto copy_view = [&](int old) {
    if (view_map.at(old) < 0) {
      const tinygltf::BufferView& v = m.bufferViews[old];
      const std::vector<unsigned char>& b = m.buffers.at(v.buffer).data;
      if (v.byteOffset + v.byteLength > b.size())
        throw InputError("heatmap.glb", "buffer view '" + v.name + "'", "reaches past its buffer");
      view_map[old] =
          add_view(b.data() + v.byteOffset, v.byteLength, v.target, static_cast<int>(v.byteStride), v.name);
    }
    return view_map[old];
  };
  for (std::size_t a = 0; a < m.accessors.size(); ++a) {
    tinygltf::Accessor& acc = r.model.accessors[a];
    if (const auto p = prim_of_indices.find(static_cast<int>(a)); p != prim_of_indices.end()) {
      const std::vector<std::uint32_t>& tris = prim_triangles[p->second];
      acc.bufferView = add_view(reinterpret_cast<const unsigned char*>(tris.data()), tris.size() * 4,
                                TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER, 0, acc.name);
      acc.byteOffset = 0;
      acc.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
      acc.count = tris.size();
      acc.minValues.clear();
      acc.maxValues.clear();
    } else if (is_vertex_attribute[a]) {
      const int components = tinygltf::GetNumComponentsInType(acc.type);
      const int element = tinygltf::GetComponentSizeInBytes(acc.componentType) * components;
      const tinygltf::BufferView& v = m.bufferViews.at(acc.bufferView);
      const int stride = acc.ByteStride(v) > 0 ? acc.ByteStride(v) : element;
      const std::vector<unsigned char>& b = m.buffers.at(v.buffer).data;
      if (element <= 0 || v.byteOffset + v.byteLength > b.size() ||
          acc.byteOffset + (nv - 1) * stride + element > v.byteLength)
        return std::nullopt;
      const unsigned char* src = b.data() + v.byteOffset + acc.byteOffset;
      const int out_stride = (element + 3) / 4 * 4;  // vertex elements are 4-byte aligned in glTF
      std::vector<unsigned char> packed(kept.size() * out_stride, 0);
      for (std::size_t i = 0; i < kept.size(); ++i)
        std::memcpy(&packed[i * out_stride], src + kept[i] * stride, element);
      acc.bufferView = add_view(packed.data(), packed.size(), TINYGLTF_TARGET_ARRAY_BUFFER,
                                out_stride == element ? 0 : out_stride, acc.name);
      acc.byteOffset = 0;
      acc.count = kept.size();
      if (acc.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT && !acc.minValues.empty()) {
        acc.minValues.assign(components, std::numeric_limits<double>::infinity());
        acc.maxValues.assign(components, -std::numeric_limits<double>::infinity());
        for (std::size_t i = 0; i < kept.size(); ++i)
          for (int c = 0; c < components; ++c) {
            float x;
            std::memcpy(&x, &packed[i * out_stride + 4 * c], 4);
            acc.minValues[c] = std::min<double>(acc.minValues[c], x);
            acc.maxValues[c] = std::max<double>(acc.maxValues[c], x);
          }
      } else {
        acc.minValues.clear();
        acc.maxValues.clear();
      }
    } else if (acc.bufferView >= 0) {
      acc.bufferView = copy_view(acc.bufferView);
    }
  }
  for (tinygltf::Image& image : r.model.images)
    if (image.bufferView >= 0) image.bufferView = copy_view(image.bufferView);
  r.model.bufferViews = std::move(views);
  r.model.buffers.assign(1, tinygltf::Buffer{});
  r.model.buffers[0].data = std::move(data);

  auto gather = [&](const std::vector<float>& from, int k) {
    std::vector<float> to;
    if (from.empty()) return to;
    to.reserve(kept.size() * k);
    for (std::uint32_t v : kept)
      to.insert(to.end(), &from[std::size_t(v) * k], &from[std::size_t(v) * k] + k);
    return to;
  };
  r.position_mm = gather(g.position_mm, 3);
  r.normal = gather(g.normal, 3);
  r.seen = gather(g.seen, 1);
  for (const auto& tris : prim_triangles) r.triangles.insert(r.triangles.end(), tris.begin(), tris.end());
  return r;
}

}  // namespace clearfit::reports::detail
