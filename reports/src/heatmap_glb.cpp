#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/reports/colormap.hpp>
#include <clearfit/reports/heatmap_glb.hpp>

#include "report_html_glb.hpp"

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

namespace clearfit {
namespace {

constexpr double kMetresPerMm = 0.001;
const char* const kUnlit = "KHR_materials_unlit";
const char* const kReservedExtras[] = {"schema",      "quantity",   "colormap", "range",         "unit",
                                       "length_unit", "node_scale", "scenes",   "no_data_linear"};

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("HeatmapInput: " + what);
}

// nlohmann JSON → tinygltf's Value (tinygltf keeps its own JSON tree).
tinygltf::Value to_value(const nlohmann::json& j) {
  switch (j.type()) {
    case nlohmann::json::value_t::boolean:
      return tinygltf::Value(j.get<bool>());
    case nlohmann::json::value_t::number_integer:
    case nlohmann::json::value_t::number_unsigned: {
      auto v = j.get<long long>();
      if (v >= std::numeric_limits<int>::min() && v <= std::numeric_limits<int>::max()) {
        return tinygltf::Value(static_cast<int>(v));
      }
      return tinygltf::Value(static_cast<double>(v));
    }
    case nlohmann::json::value_t::number_float:
      return tinygltf::Value(j.get<double>());
    case nlohmann::json::value_t::string:
      return tinygltf::Value(j.get<std::string>());
    case nlohmann::json::value_t::array: {
      tinygltf::Value::Array a;
      for (const auto& e : j) a.push_back(to_value(e));
      return tinygltf::Value(std::move(a));
    }
    case nlohmann::json::value_t::object: {
      tinygltf::Value::Object o;
      for (const auto& [k, v] : j.items()) o[k] = to_value(v);
      return tinygltf::Value(std::move(o));
    }
    default:
      return {};
  }
}

// The model's single buffer, filled view by view (each view 4-byte aligned).
struct BufferBuilder {
  tinygltf::Model& model;
  int add_view(const void* data, std::size_t bytes, int target, const std::string& name) {
    return reports::detail::append_buffer_view(model.buffers[0].data, model.bufferViews, data, bytes, target, 0, name);
  }
  // A float accessor of `components` per element (1, 2 or 3) with min/max.
  int add_floats(const std::vector<float>& data, int components, const std::string& name) {
    int view = add_view(data.data(), data.size() * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER, name);
    tinygltf::Accessor acc;
    acc.bufferView = view;
    acc.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    acc.count = data.size() / components;
    acc.type = components == 1   ? TINYGLTF_TYPE_SCALAR
               : components == 2 ? TINYGLTF_TYPE_VEC2
                                 : TINYGLTF_TYPE_VEC3;
    acc.name = name;
    acc.minValues.assign(components, std::numeric_limits<double>::infinity());
    acc.maxValues.assign(components, -std::numeric_limits<double>::infinity());
    for (std::size_t i = 0; i < data.size(); ++i) {
      auto c = i % components;
      acc.minValues[c] = std::min<double>(acc.minValues[c], data[i]);
      acc.maxValues[c] = std::max<double>(acc.maxValues[c], data[i]);
    }
    model.accessors.push_back(std::move(acc));
    return static_cast<int>(model.accessors.size()) - 1;
  }
  int add_indices(const std::vector<std::uint32_t>& idx, const std::string& name) {
    int view =
        add_view(idx.data(), idx.size() * sizeof(std::uint32_t), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER, name);
    tinygltf::Accessor acc;
    acc.bufferView = view;
    acc.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    acc.count = idx.size();
    acc.type = TINYGLTF_TYPE_SCALAR;
    acc.name = name;
    model.accessors.push_back(std::move(acc));
    return static_cast<int>(model.accessors.size()) - 1;
  }
};

// Output vertices: a mesh vertex split by region (contact or not) and corner normal.
struct VertexSet {
  struct Key {
    int region;
    Eigen::Vector3f normal;
    std::uint32_t index;
  };
  std::vector<std::vector<Key>> by_vertex;
  std::vector<int> source;  // output vertex → mesh vertex
  std::vector<char> region;
  std::vector<Eigen::Vector3f> normal;

  explicit VertexSet(int n) : by_vertex(n) {}
  std::uint32_t get(int v, int reg, const Eigen::Vector3f& n) {
    for (const Key& k : by_vertex[v]) {
      if (k.region == reg && k.normal == n) return k.index;
    }
    auto index = static_cast<std::uint32_t>(source.size());
    by_vertex[v].push_back({reg, n, index});
    source.push_back(v);
    region.push_back(static_cast<char>(reg));
    normal.push_back(n);
    return index;
  }
};

Eigen::Vector3f unit_normal(const Vec3& corner_normal, const Vec3& face_normal) {
  Vec3 n = corner_normal.squaredNorm() > 0 ? corner_normal : face_normal;
  if (!(n.squaredNorm() > 0)) n = Vec3::UnitZ();
  Eigen::Vector3f f = n.cast<float>();
  return f / f.norm();
}

// The texture field as an 8-bit PNG through the colormap (row j of the grid = image row j).
std::vector<unsigned char> texture_png(const ChartField& field, const Colormap& cm, double lo, double hi) {
  cv::Mat bgr(field.grid.height, field.grid.width, CV_8UC3);
  for (int j = 0; j < field.grid.height; ++j) {
    for (int i = 0; i < field.grid.width; ++i) {
      Rgb8 c = cm.srgb8(normalise_to_range(field.value[field.grid.index(i, j)], lo, hi));
      bgr.at<cv::Vec3b>(j, i) = cv::Vec3b(c.b, c.g, c.r);
    }
  }
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", bgr, png)) throw std::runtime_error("write_heatmap_glb: PNG encoding failed");
  return png;
}

tinygltf::Material unlit_material(const std::string& name, int texture) {
  tinygltf::Material m;
  m.name = name;
  m.pbrMetallicRoughness.baseColorFactor = {1, 1, 1, 1};
  m.pbrMetallicRoughness.metallicFactor = 0;
  m.pbrMetallicRoughness.roughnessFactor = 1;
  m.pbrMetallicRoughness.baseColorTexture.index = texture;
  m.doubleSided = true;
  m.extensions[kUnlit] = tinygltf::Value(tinygltf::Value::Object{});
  return m;
}

}  // namespace

void HeatmapInput::validate() const {
  require(mesh != nullptr, "mesh is null");
  const auto n = static_cast<std::size_t>(mesh->num_vertices());
  require(values.size() == n,
          "values has " + std::to_string(values.size()) + " entries for " + std::to_string(n) + " vertices");
  require(seen.empty() || seen.size() == n, "seen has " + std::to_string(seen.size()) + " entries");
  require(normals == nullptr || normals->corner.size() == mesh->faces.size(),
          "normals do not match the faces");
  require(chart == nullptr || chart->uv.size() == n, "chart uv does not match the vertices");
  require(texture == nullptr || chart != nullptr, "texture given without a chart");
  require(texture == nullptr || (texture->grid.width > 0 && texture->grid.height > 0 &&
                                 texture->grid.texel_mm > 0 && texture->value.size() == texture->grid.size()),
          "texture grid is empty or its values do not match it");
  require(std::isfinite(range_lo) && std::isfinite(range_hi) && range_lo < range_hi,
          "range [" + std::to_string(range_lo) + ", " + std::to_string(range_hi) + "] is not finite lo < hi");
  for (const VertexScalar& s : scalars) {
    require(s.name.size() > 1 && s.name[0] == '_' && s.name != "_SEEN",
            "scalar name '" + s.name + "' must start with '_' and not be _SEEN");
    require(s.values.size() == n,
            "scalar " + s.name + " has " + std::to_string(s.values.size()) + " entries");
  }
  for (const HeatmapMarker& h : hotspots) {
    require(h.position_mm.allFinite(), "hotspot " + std::to_string(h.id) + " position is not finite");
  }
  require(extras.is_object(), "extras must be a JSON object");
  for (const char* key : kReservedExtras)
    require(!extras.contains(key), std::string("extras may not set '") + key + "'");
  Colormap::get(colormap);
}

namespace {

/// The glb's vertex streams: contact faces' corners apart from the rest (a vertex on both is split),
/// coloured, with chart texture coordinates, _SEEN and the scalars.
struct VertexStreams {
  std::vector<float> position, normal, colour, texcoord, seen;
  std::vector<std::vector<float>> scalars;
  std::vector<std::uint32_t> contact_idx, rest_idx;
  std::size_t count() const { return position.size() / 3; }
};

/// Texture coordinates map chart uv (mm) onto the texel grid's extent (or the chart's bounds): origin and extent.
std::pair<Vec2, Vec2> texcoord_frame(const HeatmapInput& input) {
  if (input.texture) {
    const ChartGrid& g = input.texture->grid;
    return {g.uv_origin - Vec2::Constant(0.5 * g.texel_mm), g.texel_mm * Vec2(g.width, g.height)};
  }
  if (input.chart) return {input.chart->uv_min, (input.chart->uv_max - input.chart->uv_min).cwiseMax(Vec2::Constant(1e-12))};
  return {Vec2::Zero(), Vec2::Ones()};
}

VertexStreams vertex_streams(const HeatmapInput& input, const Colormap& cm) {
  const Mesh& mesh = *input.mesh;
  CornerNormals computed;
  if (input.normals == nullptr) computed = compute_corner_normals(mesh);
  const CornerNormals& normals = input.normals ? *input.normals : computed;
  // Which faces are contact faces (those the chart covers).
  std::vector<char> contact(mesh.faces.size(), input.chart == nullptr ? 1 : 0);
  if (input.chart) {
    for (int f : input.chart->faces) contact.at(f) = 1;
  }
  VertexStreams out;
  VertexSet vs(mesh.num_vertices());
  for (int f = 0; f < mesh.num_faces(); ++f) {
    Vec3 fn = mesh.face_normal(f);
    for (int k = 0; k < 3; ++k) {
      std::uint32_t i = vs.get(mesh.faces[f][k], contact[f], unit_normal(normals.corner[f][k], fn));
      (contact[f] ? out.contact_idx : out.rest_idx).push_back(i);
    }
  }
  const auto [uv0, uv_extent] = texcoord_frame(input);
  const std::size_t n_out = vs.source.size();
  out.scalars.resize(input.scalars.size());
  out.position.reserve(3 * n_out);
  const Eigen::Vector3f grey = cm.no_data_linear();
  for (std::size_t o = 0; o < n_out; ++o) {
    const int v = vs.source[o];
    const bool on_contact = vs.region[o] != 0;
    const float value = input.values[v];
    const bool seen = on_contact && (input.seen.empty() ? std::isfinite(value) : input.seen[v] != 0);
    for (int c = 0; c < 3; ++c) out.position.push_back(static_cast<float>(mesh.vertices[v][c]));
    for (int c = 0; c < 3; ++c) out.normal.push_back(vs.normal[o][c]);
    Eigen::Vector3f rgb = seen && std::isfinite(value) ? cm.linear(normalise_to_range(value, input.range_lo, input.range_hi)) : grey;
    for (int c = 0; c < 3; ++c) out.colour.push_back(rgb[c]);
    Vec2 uv = Vec2::Zero();
    if (input.chart && on_contact && input.chart->uv[v].allFinite()) uv = (input.chart->uv[v] - uv0).cwiseQuotient(uv_extent);
    out.texcoord.push_back(static_cast<float>(uv[0]));
    out.texcoord.push_back(static_cast<float>(uv[1]));
    out.seen.push_back(seen ? 1.0f : 0.0f);
    for (std::size_t s = 0; s < input.scalars.size(); ++s) {
      float x = input.scalars[s].values[v];
      out.scalars[s].push_back(seen && std::isfinite(x) ? x : 0.0f);
    }
  }
  return out;
}

/// The chart texture (PNG in the buffer, linear sampler, clamped); returns its index.
int add_chart_texture(tinygltf::Model& model, BufferBuilder& b, const HeatmapInput& input, const Colormap& cm) {
  std::vector<unsigned char> png = texture_png(*input.texture, cm, input.range_lo, input.range_hi);
  tinygltf::Image image;
  image.name = input.quantity;
  image.mimeType = "image/png";
  image.bufferView = b.add_view(png.data(), png.size(), 0, "texture.png");
  model.images.push_back(std::move(image));
  tinygltf::Sampler sampler;
  sampler.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
  sampler.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
  sampler.wrapS = sampler.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
  model.samplers.push_back(sampler);
  tinygltf::Texture texture;
  texture.source = static_cast<int>(model.images.size()) - 1;
  texture.sampler = static_cast<int>(model.samplers.size()) - 1;
  model.textures.push_back(texture);
  return static_cast<int>(model.textures.size()) - 1;
}

/// Meshes: "heatmap_vertex_colors" (mesh 0) and, with a texture, "heatmap_texture" (mesh 1).
void add_heatmap_meshes(tinygltf::Model& model, BufferBuilder& b, const HeatmapInput& input, const VertexStreams& v) {
  std::map<std::string, int> attributes;
  if (v.count() > 0) {
    attributes["POSITION"] = b.add_floats(v.position, 3, "POSITION");
    attributes["NORMAL"] = b.add_floats(v.normal, 3, "NORMAL");
    if (input.chart) attributes["TEXCOORD_0"] = b.add_floats(v.texcoord, 2, "TEXCOORD_0");
    attributes["_SEEN"] = b.add_floats(v.seen, 1, "_SEEN");
    for (std::size_t s = 0; s < input.scalars.size(); ++s) {
      attributes[input.scalars[s].name] = b.add_floats(v.scalars[s], 1, input.scalars[s].name);
    }
  }
  const int colour_accessor = v.count() > 0 ? b.add_floats(v.colour, 3, "COLOR_0") : -1;
  auto primitive = [&](const std::vector<std::uint32_t>& idx, const std::string& name, int material) {
    tinygltf::Primitive p;
    p.mode = TINYGLTF_MODE_TRIANGLES;
    p.indices = b.add_indices(idx, name);
    p.attributes = attributes;
    p.attributes["COLOR_0"] = colour_accessor;
    p.material = material;
    return p;
  };
  std::vector<tinygltf::Primitive> rest, coloured_contact;
  if (!v.rest_idx.empty()) rest.push_back(primitive(v.rest_idx, "rest", 0));
  if (!v.contact_idx.empty()) coloured_contact.push_back(primitive(v.contact_idx, "contact", 0));
  tinygltf::Mesh vertex_mesh;
  vertex_mesh.name = "heatmap_vertex_colors";
  vertex_mesh.primitives = coloured_contact;
  vertex_mesh.primitives.insert(vertex_mesh.primitives.end(), rest.begin(), rest.end());
  if (vertex_mesh.primitives.empty()) throw std::invalid_argument("write_heatmap_glb: the mesh has no faces");
  model.meshes.push_back(vertex_mesh);
  if (input.texture) {
    tinygltf::Mesh textured;
    textured.name = "heatmap_texture";
    if (!coloured_contact.empty()) {
      tinygltf::Primitive p = coloured_contact[0];
      p.attributes.erase("COLOR_0");
      p.material = 1;
      textured.primitives.push_back(p);
    }
    textured.primitives.insert(textured.primitives.end(), rest.begin(), rest.end());
    model.meshes.push_back(textured);
  }
}

/// The scenes ("texture" first when there is one, then "vertex_colors"), each the part in metres
/// plus the hotspot markers; returns the scene index by name.
nlohmann::json add_scenes(tinygltf::Model& model, const HeatmapInput& input) {
  const std::vector<double> scale(3, kMetresPerMm);
  auto add_node = [&](tinygltf::Node node) {
    model.nodes.push_back(std::move(node));
    return static_cast<int>(model.nodes.size()) - 1;
  };
  int markers = -1;
  if (!input.hotspots.empty()) {
    tinygltf::Node root;
    root.name = "hotspots";
    root.scale = scale;
    for (const HeatmapMarker& h : input.hotspots) {
      tinygltf::Node child;
      child.name = "hotspot " + std::to_string(h.id);
      child.translation = {h.position_mm[0], h.position_mm[1], h.position_mm[2]};
      child.extras = to_value(nlohmann::json{{"id", h.id}, {"label", h.label}});
      root.children.push_back(add_node(std::move(child)));
    }
    markers = add_node(std::move(root));
  }
  auto add_scene = [&](const std::string& name, int mesh_index) {
    tinygltf::Node node;
    node.name = "part";
    node.mesh = mesh_index;
    node.scale = scale;
    tinygltf::Scene scene;
    scene.name = name;
    scene.nodes.push_back(add_node(std::move(node)));
    if (markers >= 0) scene.nodes.push_back(markers);
    model.scenes.push_back(std::move(scene));
  };
  nlohmann::json scenes;
  if (input.texture) {
    add_scene("texture", 1);
    scenes["texture"] = 0;
  }
  scenes["vertex_colors"] = static_cast<int>(model.scenes.size());
  add_scene("vertex_colors", 0);
  model.defaultScene = 0;
  return scenes;
}

}  // namespace

void write_heatmap_glb(const HeatmapInput& input, const std::filesystem::path& path) {
  input.validate();
  const Colormap& cm = Colormap::get(input.colormap);
  const VertexStreams streams = vertex_streams(input, cm);

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "clearfit";
  model.buffers.resize(1);
  BufferBuilder b{model};
  const int texture_index = input.texture ? add_chart_texture(model, b, input, cm) : -1;
  model.materials.push_back(unlit_material("vertex_colors", -1));
  if (input.texture) model.materials.push_back(unlit_material("texture", texture_index));
  model.extensionsUsed.push_back(kUnlit);
  add_heatmap_meshes(model, b, input, streams);
  const nlohmann::json scenes = add_scenes(model, input);

  const Eigen::Vector3f grey = cm.no_data_linear();
  nlohmann::json info = input.extras;
  info["schema"] = "clearfit.heatmap/1";
  info["quantity"] = input.quantity;
  info["colormap"] = input.colormap;
  info["range"] = {input.range_lo, input.range_hi};
  info["unit"] = input.unit;
  info["length_unit"] = "mm";
  info["node_scale"] = kMetresPerMm;
  info["scenes"] = scenes;
  info["no_data_linear"] = {grey[0], grey[1], grey[2]};
  model.asset.extras = to_value(nlohmann::json{{"clearfit", info}});

  write_path_atomically(path, [&](const std::filesystem::path& temp) {
    tinygltf::TinyGLTF writer;
    if (!writer.WriteGltfSceneToFile(&model, temp.string(), true, true, false, true)) {
      throw InputError(path.string(), "", "could not write the glTF file",
                       "check the folder exists and is writable");
    }
  });
}

void write_difference_glb(HeatmapInput input, double max_abs, const std::filesystem::path& path) {
  if (!(max_abs >= 0) || !std::isfinite(max_abs)) {
    throw std::invalid_argument("write_difference_glb: max_abs must be finite and >= 0");
  }
  if (max_abs == 0) {
    auto widen = [&](float v) {
      if (std::isfinite(v)) max_abs = std::max(max_abs, static_cast<double>(std::abs(v)));
    };
    std::for_each(input.values.begin(), input.values.end(), widen);
    if (input.texture) std::for_each(input.texture->value.begin(), input.texture->value.end(), widen);
    if (max_abs == 0) max_abs = 1;
  }
  if (!Colormap::get(input.colormap).diverging()) input.colormap = "coolwarm";
  input.range_lo = -max_abs;
  input.range_hi = max_abs;
  write_heatmap_glb(input, path);
}

}  // namespace clearfit
