// Reading heatmap .glb files back (tinygltf), shared by report.html and compare.
#include "report_html_glb.hpp"

#include <clearfit/error.hpp>

#include <cstring>
#include <sstream>

namespace clearfit::reports::detail {

int append_buffer_view(std::vector<unsigned char>& buffer, std::vector<tinygltf::BufferView>& views,
                       const void* data, std::size_t bytes, int target, int stride, const std::string& name) {
  buffer.resize((buffer.size() + 3) / 4 * 4, 0);
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = buffer.size();
  view.byteLength = bytes;
  view.byteStride = stride;
  view.target = target;
  view.name = name;
  const auto* p = static_cast<const unsigned char*>(data);
  buffer.insert(buffer.end(), p, p + bytes);
  views.push_back(std::move(view));
  return static_cast<int>(views.size()) - 1;
}
namespace {

const unsigned char* accessor_data(const tinygltf::Model& model, const tinygltf::Accessor& acc, int& stride,
                                   int element_bytes, const std::string& file) {
  if (acc.bufferView < 0 || acc.bufferView >= static_cast<int>(model.bufferViews.size()))
    throw InputError(file, "accessor '" + acc.name + "'", "has no buffer view (sparse or empty accessors are not read)");
  const tinygltf::BufferView& view = model.bufferViews[acc.bufferView];
  const tinygltf::Buffer& buffer = model.buffers.at(view.buffer);
  stride = acc.ByteStride(view);
  if (stride <= 0) stride = element_bytes;
  const std::size_t start = view.byteOffset + acc.byteOffset;
  const std::size_t need = acc.count == 0 ? 0 : start + (acc.count - 1) * stride + element_bytes;
  if (need > buffer.data.size() || acc.byteOffset + (acc.count ? (acc.count - 1) * stride + element_bytes : 0) > view.byteLength)
    throw InputError(file, "accessor '" + acc.name + "'", "reaches past the end of its buffer");
  return buffer.data.data() + start;
}

}  // namespace

std::vector<float> read_floats(const tinygltf::Model& model, int index, int components, const std::string& file) {
  const tinygltf::Accessor& acc = model.accessors.at(index);
  const int have = tinygltf::GetNumComponentsInType(acc.type);
  if (acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT || have != components)
    throw InputError(file, "accessor '" + acc.name + "'",
                     "expected " + std::to_string(components) + " float component(s) per element");
  int stride = 0;
  const unsigned char* p = accessor_data(model, acc, stride, components * 4, file);
  std::vector<float> out(acc.count * components);
  for (std::size_t i = 0; i < acc.count; ++i) std::memcpy(&out[i * components], p + i * stride, components * 4);
  return out;
}

std::vector<float> HeatmapGlb::scalar(const std::string& name) const {
  const auto& attributes = model.meshes[mesh].primitives[0].attributes;
  const auto it = attributes.find(name);
  if (it == attributes.end()) return {};
  return read_floats(model, it->second, 1, name);
}

HeatmapGlb load_heatmap_glb(const std::filesystem::path& path) {
  HeatmapGlb g;
  const std::string file = path.string();
  tinygltf::TinyGLTF loader;
  loader.SetStoreOriginalJSONForExtrasAndExtensions(true);
  // Textures stay encoded in their buffer views: nothing here needs their pixels.
  loader.SetImageLoader([](tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int,
                           void*) { return true; },
                        nullptr);
  std::string err, warn;
  if (!std::filesystem::is_regular_file(path)) throw InputError(file, "", "not found");
  if (!loader.LoadBinaryFromFile(&g.model, &err, &warn, file))
    throw InputError(file, "", "is not a readable binary glTF (.glb): " + err, "write it again with clearfit assess");
  if (!g.model.asset.extras_json_string.empty()) {
    const auto extras = nlohmann::json::parse(g.model.asset.extras_json_string, nullptr, false);
    if (extras.is_object() && extras.contains("clearfit") && extras["clearfit"].is_object()) g.info = extras["clearfit"];
  }
  if (!g.info.is_object()) g.info = nlohmann::json::object();
  for (std::size_t m = 0; m < g.model.meshes.size(); ++m)
    if (g.mesh < 0 || g.model.meshes[m].name == "heatmap_vertex_colors") g.mesh = static_cast<int>(m);
  if (g.mesh < 0 || g.model.meshes[g.mesh].primitives.empty()) throw InputError(file, "meshes", "the file holds no mesh");
  const auto& prims = g.model.meshes[g.mesh].primitives;
  const auto& attributes = prims[0].attributes;
  const auto pos = attributes.find("POSITION");
  if (pos == attributes.end()) throw InputError(file, "mesh 0", "has no POSITION attribute");
  g.position_mm = read_floats(g.model, pos->second, 3, file);
  if (const auto n = attributes.find("NORMAL"); n != attributes.end()) g.normal = read_floats(g.model, n->second, 3, file);
  if (const auto s = attributes.find("_SEEN"); s != attributes.end()) g.seen = read_floats(g.model, s->second, 1, file);
  else g.seen.assign(g.vertex_count(), 1.0f);
  for (const tinygltf::Primitive& p : prims) {
    if (p.mode != TINYGLTF_MODE_TRIANGLES && p.mode != -1)
      throw InputError(file, "mesh '" + g.model.meshes[g.mesh].name + "'", "has a primitive that is not triangles");
    const auto pp = p.attributes.find("POSITION");
    if (pp == p.attributes.end() || pp->second != pos->second)
      throw InputError(file, "mesh '" + g.model.meshes[g.mesh].name + "'",
                       "primitives do not share one vertex set (not a clearfit heatmap)");
    if (p.indices < 0) throw InputError(file, "mesh '" + g.model.meshes[g.mesh].name + "'", "has a primitive without indices");
    const tinygltf::Accessor& acc = g.model.accessors.at(p.indices);
    const int bytes = tinygltf::GetComponentSizeInBytes(acc.componentType);
    if (bytes != 1 && bytes != 2 && bytes != 4) throw InputError(file, "accessor '" + acc.name + "'", "bad index type");
    int stride = 0;
    const unsigned char* d = accessor_data(g.model, acc, stride, bytes, file);
    for (std::size_t i = 0; i < acc.count; ++i) {
      std::uint32_t v = 0;
      if (bytes == 1) v = d[i * stride];
      else if (bytes == 2) { std::uint16_t s; std::memcpy(&s, d + i * stride, 2); v = s; }
      else std::memcpy(&v, d + i * stride, 4);
      if (v >= g.vertex_count()) throw InputError(file, "accessor '" + acc.name + "'", "index out of range");
      g.triangles.push_back(v);
    }
  }
  if (g.triangles.size() % 3 != 0) throw InputError(file, "indices", "count is not a multiple of 3");
  return g;
}

std::string to_glb_bytes(const tinygltf::Model& model) {
  std::ostringstream out;
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&model, out, false, true))
    throw std::runtime_error("to_glb_bytes: tinygltf could not serialise the model");
  return out.str();
}

}  // namespace clearfit::reports::detail
