// glTF 2.0 (.gltf and .glb) through tinygltf (Debian's shared library: no
// TINYGLTF_IMPLEMENTATION here). glTF lengths are metres. The default scene's
// node tree is walked in order; each node's mesh is placed by the node's world
// transform (matrix, or translation·rotation·scale) and becomes the group named
// after the node (else the mesh, else "mesh <i>"). Triangle lists, strips and
// fans are read; points and lines are skipped with a note.
#include "import_internal.hpp"

#include <tiny_gltf.h>

#include <Eigen/Geometry>
#include <cstring>

namespace clearfit::detail {
namespace {

constexpr int kFloat = TINYGLTF_COMPONENT_TYPE_FLOAT;

struct Reader {
  const tinygltf::Model& model;
  const std::string& name;
  RawMesh& raw;
  int skipped = 0;

  const tinygltf::Accessor& accessor(int index, const std::string& where) const {
    if (index < 0 || index >= static_cast<int>(model.accessors.size()))
      throw InputError(name, where, "accessor " + std::to_string(index) + " does not exist");
    return model.accessors[index];
  }

  // Start of an accessor's data and its stride, after checking it lies inside its buffer.
  const unsigned char* data(int index, size_t elem_size, const std::string& where, size_t& stride) const {
    const auto& acc = accessor(index, where);
    const std::string me = where + ", accessor " + std::to_string(index);
    if (acc.sparse.isSparse) throw InputError(name, me, "sparse accessors are not supported");
    if (acc.bufferView < 0 || acc.bufferView >= static_cast<int>(model.bufferViews.size()))
      throw InputError(name, me, "has no valid bufferView");
    const auto& view = model.bufferViews[acc.bufferView];
    if (view.buffer < 0 || view.buffer >= static_cast<int>(model.buffers.size()))
      throw InputError(name, me, "its bufferView names no valid buffer");
    const auto& buffer = model.buffers[view.buffer].data;
    stride = view.byteStride ? view.byteStride : elem_size;
    const size_t need = acc.byteOffset + (acc.count ? stride * (acc.count - 1) + elem_size : 0);
    if (need > view.byteLength || view.byteOffset + view.byteLength > buffer.size())
      throw InputError(name, me, "reaches past the end of its buffer");
    return buffer.data() + view.byteOffset + acc.byteOffset;
  }

  void primitive(const tinygltf::Primitive& prim, const Eigen::Affine3d& world, int group, const std::string& where) {
    const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN) {
      ++skipped;
      return;
    }
    auto pos = prim.attributes.find("POSITION");
    if (pos == prim.attributes.end()) throw InputError(name, where, "has no POSITION attribute");
    const auto& pacc = accessor(pos->second, where + " POSITION");
    if (pacc.type != TINYGLTF_TYPE_VEC3 || pacc.componentType != kFloat)
      throw InputError(name, where, "POSITION must be float VEC3", "quantized positions are not supported");
    size_t stride = 0;
    const unsigned char* p = data(pos->second, 12, where + " POSITION", stride);
    const int base = static_cast<int>(raw.vertices.size());
    for (size_t i = 0; i < pacc.count; ++i) {
      float xyz[3];
      std::memcpy(xyz, p + i * stride, sizeof xyz);
      const Vec3 v(xyz[0], xyz[1], xyz[2]);
      if (!v.allFinite())
        throw InputError(name, where + ", vertex " + std::to_string(i), "coordinate is not finite (nan or inf)");
      raw.vertices.push_back(world * v);
    }
    std::vector<std::uint32_t> idx;
    if (prim.indices >= 0) {
      const auto& iacc = accessor(prim.indices, where + " indices");
      const int ct = iacc.componentType;
      const size_t size = ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ? 1 : ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT ? 2
                          : ct == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT ? 4 : 0;
      if (size == 0 || iacc.type != TINYGLTF_TYPE_SCALAR)
        throw InputError(name, where, "indices must be unsigned byte, short or int scalars");
      const unsigned char* d = data(prim.indices, size, where + " indices", stride);
      idx.resize(iacc.count);
      for (size_t i = 0; i < iacc.count; ++i) {
        std::uint32_t v = 0;  // little-endian, as glTF
        std::memcpy(&v, d + i * stride, size);
        idx[i] = v;
      }
    } else {
      idx.resize(pacc.count);
      for (size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<std::uint32_t>(i);
    }
    auto add = [&](size_t a, size_t b, size_t c, size_t t) {
      for (size_t k : {a, b, c})
        if (idx[k] >= pacc.count)
          throw InputError(name, where + ", triangle " + std::to_string(t),
                           "index " + std::to_string(idx[k]) + " is out of range (" + std::to_string(pacc.count) + " vertices)");
      raw.polygons.push_back({base + static_cast<int>(idx[a]), base + static_cast<int>(idx[b]), base + static_cast<int>(idx[c])});
      raw.polygon_group.push_back(group);
    };
    if (mode == TINYGLTF_MODE_TRIANGLES)
      for (size_t t = 0; 3 * t + 2 < idx.size(); ++t) add(3 * t, 3 * t + 1, 3 * t + 2, t);
    else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP)
      for (size_t t = 0; t + 2 < idx.size(); ++t) t % 2 ? add(t + 1, t, t + 2, t) : add(t, t + 1, t + 2, t);
    else
      for (size_t t = 0; t + 2 < idx.size(); ++t) add(0, t + 1, t + 2, t);
  }

  void mesh(int index, const Eigen::Affine3d& world, const std::string& group_name) {
    if (index < 0 || index >= static_cast<int>(model.meshes.size()))
      throw InputError(name, group_name, "names mesh " + std::to_string(index) + ", which does not exist");
    const auto& m = model.meshes[index];
    const int group = raw.group_index(group_name);
    for (size_t p = 0; p < m.primitives.size(); ++p)
      primitive(m.primitives[p], world, group, "mesh " + std::to_string(index) + " primitive " + std::to_string(p));
  }

  void node(int index, const Eigen::Affine3d& parent, int depth) {
    if (index < 0 || index >= static_cast<int>(model.nodes.size()))
      throw InputError(name, "", "node " + std::to_string(index) + " does not exist");
    if (depth > 64) throw InputError(name, "node " + std::to_string(index), "nodes nest more than 64 deep (a cycle?)");
    const auto& n = model.nodes[index];
    Eigen::Affine3d local = Eigen::Affine3d::Identity();
    if (n.matrix.size() == 16) {
      local.matrix() = Eigen::Map<const Eigen::Matrix4d>(n.matrix.data());  // column-major, as glTF
    } else {
      if (n.translation.size() == 3) local.translate(Vec3(n.translation[0], n.translation[1], n.translation[2]));
      if (n.rotation.size() == 4)
        local.rotate(Eigen::Quaterniond(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]).normalized());
      if (n.scale.size() == 3) local.scale(Vec3(n.scale[0], n.scale[1], n.scale[2]));
    }
    const Eigen::Affine3d world = parent * local;
    if (n.mesh >= 0) {
      std::string group = n.name;
      if (group.empty() && n.mesh < static_cast<int>(model.meshes.size())) group = model.meshes[n.mesh].name;
      if (group.empty()) group = "mesh " + std::to_string(n.mesh);
      mesh(n.mesh, world, group);
    }
    for (int child : n.children) node(child, world, depth + 1);
  }
};

}  // namespace

RawMesh read_gltf(const std::filesystem::path& path, bool binary) {
  const std::string name = display(path);
  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  std::string err, warn;
  const bool ok = binary ? loader.LoadBinaryFromFile(&model, &err, &warn, path.string())
                         : loader.LoadASCIIFromFile(&model, &err, &warn, path.string());
  if (!ok) {
    while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
    throw InputError(name, "", "tinygltf could not read it: " + err, "check the file is valid glTF 2.0");
  }
  RawMesh raw;
  raw.file_unit = LengthUnit::metre;
  if (!warn.empty()) raw.notes.push_back("tinygltf: " + warn);
  Reader reader{model, name, raw};
  const int scene = model.defaultScene >= 0 ? model.defaultScene : (model.scenes.empty() ? -1 : 0);
  if (scene >= static_cast<int>(model.scenes.size())) throw InputError(name, "scene", "the default scene does not exist");
  if (scene >= 0) {
    for (int n : model.scenes[scene].nodes) reader.node(n, Eigen::Affine3d::Identity(), 0);
  } else {  // no scene: every mesh, untransformed
    for (size_t m = 0; m < model.meshes.size(); ++m)
      reader.mesh(static_cast<int>(m), Eigen::Affine3d::Identity(),
                  model.meshes[m].name.empty() ? "mesh " + std::to_string(m) : model.meshes[m].name);
    if (!model.meshes.empty()) raw.notes.push_back("the glTF has no scene; read every mesh untransformed");
  }
  if (reader.skipped) raw.notes.push_back("skipped " + std::to_string(reader.skipped) + " point or line primitives");
  if (raw.polygons.empty())
    throw InputError(name, "", "holds no triangles (no triangle primitive in its scene)",
                     "export the part as a triangle mesh");
  return raw;
}

}  // namespace clearfit::detail
