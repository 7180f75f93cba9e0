// PLY through OpenMesh's reader, and STL/PLY/OFF writing through its writers (OFF is read
// in import_ply_off_check.cpp).
// Reading goes through our own BaseImporter, not a mesh kernel: OpenMesh's mesh
// importer drops faces with repeated vertices and re-adds non-manifold faces
// with duplicated vertices, which would break the file's face order; the
// importer below records vertices and faces exactly as the reader announces them.
// OpenMesh's readers trust their input (a non-number, a damaged header or a
// negative list length make them read garbage, crash or allocate without bound),
// so the file's structure is checked first (import_ply_off_check.cpp).
#include "import_internal.hpp"

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/IO/IOManager.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>

#include <array>
#include <mutex>

namespace clearfit::detail {
namespace {

using namespace OpenMesh;

// OpenMesh prints to its global omerr/omlog/omout streams (std::cerr/std::clog/
// std::cout). While one of these lives they are switched off. (Capturing them into
// import_notes is not done: mostream::disconnect leaks its target object, which
// LeakSanitizer reports; our own checks name the faults that matter instead.)
class OmQuiet {
 public:
  OmQuiet() : lock_(mutex()) {
    for (int i = 0; i < 3; ++i) {
      was_[i] = streams()[i]->is_enabled();
      streams()[i]->disable();
    }
  }
  ~OmQuiet() {
    for (int i = 0; i < 3; ++i)
      if (was_[i]) streams()[i]->enable();
  }
  OmQuiet(const OmQuiet&) = delete;
  OmQuiet& operator=(const OmQuiet&) = delete;

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  static std::array<mostream*, 3> streams() { return {&omerr(), &omlog(), &omout()}; }
  std::lock_guard<std::mutex> lock_;
  bool was_[3] = {};
};

// Records what a reader announces, in order; ignores everything but positions and faces.
class Recorder : public IO::BaseImporter {
 public:
  explicit Recorder(RawMesh& raw) : raw_(raw) {}
  VertexHandle add_vertex(const Vec3f& p) override { return push(Vec3(p[0], p[1], p[2])); }
  VertexHandle add_vertex(const Vec3d& p) override { return push(Vec3(p[0], p[1], p[2])); }
  VertexHandle add_vertex() override { return push(Vec3::Zero()); }
  void set_point(VertexHandle v, const Vec3f& p) override {
    if (v.idx() >= 0 && v.idx() < static_cast<int>(raw_.vertices.size())) raw_.vertices[v.idx()] = Vec3(p[0], p[1], p[2]);
  }
  FaceHandle add_face(const VHandles& vh) override {
    std::vector<int> poly;
    poly.reserve(vh.size());
    for (auto v : vh) poly.push_back(v.idx());
    raw_.polygons.push_back(std::move(poly));
    return FaceHandle(static_cast<int>(raw_.polygons.size()) - 1);
  }
  size_t n_vertices() const override { return raw_.vertices.size(); }
  size_t n_faces() const override { return raw_.polygons.size(); }
  size_t n_edges() const override { return 0; }

  HalfedgeHandle add_edge(VertexHandle, VertexHandle) override { return HalfedgeHandle(); }
  FaceHandle add_face(HalfedgeHandle) override { return FaceHandle(); }
  void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec2f>&) override {}
  void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec3f>&) override {}
  void set_face_texindex(FaceHandle, int) override {}
  void set_halfedge(VertexHandle, HalfedgeHandle) override {}
  void set_normal(VertexHandle, const Vec3f&) override {}
  void set_normal(VertexHandle, const Vec3d&) override {}
  void set_color(VertexHandle, const Vec3uc&) override {}
  void set_color(VertexHandle, const Vec4uc&) override {}
  void set_color(VertexHandle, const Vec3f&) override {}
  void set_color(VertexHandle, const Vec4f&) override {}
  void set_texcoord(VertexHandle, const Vec2f&) override {}
  void set_status(VertexHandle, const Attributes::StatusInfo&) override {}
  void set_next(HalfedgeHandle, HalfedgeHandle) override {}
  void set_face(HalfedgeHandle, FaceHandle) override {}
  void request_face_texcoords2D() override {}
  void set_texcoord(HalfedgeHandle, const Vec2f&) override {}
  void set_texcoord(VertexHandle, const Vec3f&) override {}
  void set_texcoord(HalfedgeHandle, const Vec3f&) override {}
  void set_status(HalfedgeHandle, const Attributes::StatusInfo&) override {}
  void set_color(EdgeHandle, const Vec3uc&) override {}
  void set_color(EdgeHandle, const Vec4uc&) override {}
  void set_color(EdgeHandle, const Vec3f&) override {}
  void set_color(EdgeHandle, const Vec4f&) override {}
  void set_status(EdgeHandle, const Attributes::StatusInfo&) override {}
  void set_normal(FaceHandle, const Vec3f&) override {}
  void set_normal(FaceHandle, const Vec3d&) override {}
  void set_color(FaceHandle, const Vec3uc&) override {}
  void set_color(FaceHandle, const Vec4uc&) override {}
  void set_color(FaceHandle, const Vec3f&) override {}
  void set_color(FaceHandle, const Vec4f&) override {}
  void set_status(FaceHandle, const Attributes::StatusInfo&) override {}
  void add_texture_information(int, std::string) override {}

 private:
  VertexHandle push(const Vec3& p) {
    raw_.vertices.push_back(p);
    return VertexHandle(static_cast<int>(raw_.vertices.size()) - 1);
  }
  RawMesh& raw_;
};

}  // namespace

RawMesh read_ply(const std::filesystem::path& path) {
  const std::string name = display(path);
  const PlyOffCounts declared = check_ply(read_file_bytes(path), name);
  RawMesh raw;
  Recorder recorder(raw);
  IO::Options opt;
  bool ok = false;
  {
    OmQuiet quiet;
    try {
      ok = IO::IOManager().read(path.string(), recorder, opt);
    } catch (const std::exception& e) {
      throw InputError(name, "", std::string("OpenMesh failed to read it: ") + e.what());
    }
  }
  if (!ok) throw InputError(name, "", "OpenMesh could not read it", "check the file is a valid PLY file");
  if (raw.vertices.size() != declared.vertices || raw.polygons.size() != declared.faces)
    throw InputError(name, "", "declares " + std::to_string(declared.vertices) + " vertices and " +
                                   std::to_string(declared.faces) + " faces but " + std::to_string(raw.vertices.size()) +
                                   " and " + std::to_string(raw.polygons.size()) + " were read");
  return raw;
}

void write_openmesh(const Mesh& mesh, const std::filesystem::path& path, const std::string& ext) {
  PolyMesh_ArrayKernelT<> om;
  std::vector<VertexHandle> vh;
  vh.reserve(mesh.vertices.size());
  OmQuiet quiet;  // add_face prints when it meets a non-manifold face
  auto point = [](const Vec3& p) { return PolyMesh_ArrayKernelT<>::Point(float(p.x()), float(p.y()), float(p.z())); };
  for (const auto& p : mesh.vertices) vh.push_back(om.add_vertex(point(p)));
  for (const auto& f : mesh.faces) {
    FaceHandle fh;
    if (f[0] != f[1] && f[1] != f[2] && f[0] != f[2]) fh = om.add_face(vh[f[0]], vh[f[1]], vh[f[2]]);
    if (!fh.is_valid())  // repeated or non-manifold: the face gets its own copies of its vertices
      om.add_face(om.add_vertex(point(mesh.vertices[f[0]])), om.add_vertex(point(mesh.vertices[f[1]])),
                  om.add_vertex(point(mesh.vertices[f[2]])));
  }
  const IO::Options opt = ext == ".off" ? IO::Options::Default : IO::Options::Binary;
  if (!IO::write_mesh(om, path.string(), opt, 9)) throw std::runtime_error("OpenMesh could not write it");
}

}  // namespace clearfit::detail
