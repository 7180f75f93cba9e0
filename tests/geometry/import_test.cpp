// Mesh import/export: round trips through every format, files written by an
// independent route (hand-written text, hand-packed binary STL, tinygltf, 3MF
// packed by hand), units, and every bad-input case naming the file.
#include <clearfit/error.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/geometry/shapes.hpp>

#include "../support/zip_package.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tiny_gltf.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>

// lib3mf 1.8 leaks a few hundred bytes inside libzip on every 3MF read (a ten-line
// program that only reads and releases reproduces it); LeakSanitizer, when linked in,
// is told to ignore leaks from libzip. Unused in a build without sanitizers.
extern "C" const char* __lsan_default_suppressions() { return "leak:libzip.so\n"; }

namespace clearfit {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

class Import : public ::testing::Test {
 protected:
  void SetUp() override {
    static int n = 0;
    dir_ = fs::temp_directory_path() / ("clearfit_import_test_" + std::to_string(::getpid()) + "_" + std::to_string(n++));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path file(const std::string& name) const { return dir_ / name; }
  fs::path text(const std::string& name, const std::string& contents) const {
    std::ofstream(file(name), std::ios::binary) << contents;
    return file(name);
  }
  fs::path bytes(const std::string& name, const std::string& contents) const { return text(name, contents); }
  fs::path dir_;
};

// A tetrahedron with two groups, outward faces.
Mesh tetra() {
  Mesh m;
  m.vertices = {Vec3(0, 0, 0), Vec3(10, 0, 0), Vec3(0, 20, 0), Vec3(0, 0, 30.5)};
  m.faces = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
  m.file_face = {0, 1, 2, 3};
  m.groups = {"base", "sides"};
  m.face_group = {0, 1, 1, 1};
  return m;
}

// Same triangles, same order, same corner positions (within tol).
void expect_same_corners(const Mesh& a, const Mesh& b, double tol) {
  ASSERT_EQ(a.num_faces(), b.num_faces());
  for (int f = 0; f < a.num_faces(); ++f)
    for (int k = 0; k < 3; ++k)
      ASSERT_LE((a.corner(f, k) - b.corner(f, k)).norm(), tol) << "face " << f << " corner " << k;
}

std::vector<std::string> group_per_face(const Mesh& m) {
  std::vector<std::string> out;
  for (int f = 0; f < m.num_faces(); ++f)
    out.push_back(m.face_group.empty() || m.face_group[f] < 0 ? "" : m.groups[m.face_group[f]]);
  return out;
}

// Runs `load`, expects an InputError whose file is `path` and whose message holds `element`.
template <class F>
void expect_input_error(F&& load, const fs::path& path, const std::string& element) {
  try {
    load();
    ADD_FAILURE() << "no InputError for " << path;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), path.string()) << e.what();
    EXPECT_THAT(e.what(), HasSubstr(path.string()));
    EXPECT_THAT(e.what(), HasSubstr(element));
  }
}

// Binary STL packed by hand: 80-byte header, count, 50-byte records.
std::string binary_stl(const std::vector<std::array<Vec3, 3>>& tris, std::uint32_t claimed = UINT32_MAX) {
  std::string s(80, ' ');
  const std::uint32_t n = claimed == UINT32_MAX ? static_cast<std::uint32_t>(tris.size()) : claimed;
  s.append(reinterpret_cast<const char*>(&n), 4);
  for (const auto& t : tris) {
    float rec[12] = {0, 0, 1};
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) rec[3 + 3 * k + c] = static_cast<float>(t[k][c]);
    s.append(reinterpret_cast<const char*>(rec), sizeof rec);
    s.append(2, '\0');
  }
  return s;
}

const std::string kAsciiStl =
    "solid part\n"
    "facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 1 0\n endloop\nendfacet\n"
    "facet normal 0 0 1\n outer loop\n  vertex 1 0 0\n  vertex 1 1 0\n  vertex 0 1 0\n endloop\nendfacet\n"
    // degenerate: two corners coincide (OpenMesh's reader would drop it)
    "facet normal 0 0 0\n outer loop\n  vertex 1 1 0\n  vertex 1 1 0\n  vertex +2e0 3.5 -1\n endloop\nendfacet\n"
    "facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 0 1 0\n  vertex -1 0 0\n endloop\nendfacet\n"
    "endsolid part\n";

// ---------------------------------------------------------------- units

TEST(ImportUnits, ParseNamesAndConvert) {
  EXPECT_EQ(parse_length_unit("mm"), LengthUnit::millimetre);
  EXPECT_EQ(parse_length_unit(" Millimetres "), LengthUnit::millimetre);
  EXPECT_EQ(parse_length_unit("um"), LengthUnit::micrometre);
  EXPECT_EQ(parse_length_unit("microns"), LengthUnit::micrometre);
  EXPECT_EQ(parse_length_unit("cm"), LengthUnit::centimetre);
  EXPECT_EQ(parse_length_unit("m"), LengthUnit::metre);
  EXPECT_EQ(parse_length_unit("meters"), LengthUnit::metre);
  EXPECT_EQ(parse_length_unit("in"), LengthUnit::inch);
  EXPECT_EQ(parse_length_unit("inches"), LengthUnit::inch);
  EXPECT_EQ(parse_length_unit("ft"), LengthUnit::foot);
  EXPECT_EQ(parse_length_unit("feet"), LengthUnit::foot);
  EXPECT_EQ(parse_length_unit("furlong"), std::nullopt);
  EXPECT_EQ(parse_length_unit("ms"), std::nullopt);
  EXPECT_EQ(parse_length_unit(""), std::nullopt);
  for (auto u : {LengthUnit::micrometre, LengthUnit::millimetre, LengthUnit::centimetre, LengthUnit::metre,
                 LengthUnit::inch, LengthUnit::foot})
    EXPECT_EQ(parse_length_unit(to_string(u)), u);
  EXPECT_DOUBLE_EQ(millimetres_per(LengthUnit::micrometre), 0.001);
  EXPECT_DOUBLE_EQ(millimetres_per(LengthUnit::centimetre), 10);
  EXPECT_DOUBLE_EQ(millimetres_per(LengthUnit::metre), 1000);
  EXPECT_DOUBLE_EQ(millimetres_per(LengthUnit::inch), 25.4);
  EXPECT_DOUBLE_EQ(millimetres_per(LengthUnit::foot), 12 * 25.4);
}

// ---------------------------------------------------------------- STL

TEST_F(Import, AsciiStlKeepsFaceOrderAndMergesVertices) {
  const Mesh m = load_mesh(text("a.stl", kAsciiStl));
  ASSERT_EQ(m.num_faces(), 4);
  EXPECT_EQ(m.num_vertices(), 6);  // 12 corners, 6 distinct positions
  EXPECT_EQ(m.file_face, (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(m.corner(1, 1), Vec3(1, 1, 0));
  EXPECT_EQ(m.corner(2, 0), m.corner(2, 1));  // the degenerate face is kept in place
  EXPECT_EQ(m.faces[2][0], m.faces[2][1]);
  EXPECT_EQ(m.corner(2, 2), Vec3(2, 3.5, -1));
  EXPECT_EQ(m.corner(3, 2), Vec3(-1, 0, 0));
  EXPECT_EQ(m.faces[0][0], m.faces[3][0]);  // merged
  EXPECT_TRUE(m.face_group.empty());
  EXPECT_THAT(::testing::PrintToString(m.import_notes), HasSubstr("merged 12 STL corners into 6 vertices"));
  EXPECT_EQ(m.source, file("a.stl").string());
  EXPECT_EQ(m.source_units, "mm");
}

TEST_F(Import, BinaryStlPackedByHand) {
  const std::vector<std::array<Vec3, 3>> tris = {
      {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)},
      {Vec3(0.1, 0.2, 0.3), Vec3(0.1, 0.2, 0.3), Vec3(0.1, 0.2, 0.3)},  // all corners equal
      {Vec3(0, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)}};
  // Header starting with "solid" as some exporters write: still binary by its size.
  std::string b = binary_stl(tris);
  b.replace(0, 5, "solid");
  const Mesh m = load_mesh(bytes("b.stl", b));
  ASSERT_EQ(m.num_faces(), 3);
  EXPECT_EQ(m.num_vertices(), 5);
  for (int f = 0; f < 3; ++f)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(m.corner(f, k), tris[f][k].cast<float>().cast<double>()) << f << " " << k;
}

// ---------------------------------------------------------------- OBJ

TEST_F(Import, ObjGroupsQuadsAndOrder) {
  const fs::path p = text("g.obj",
                          "# hand-written\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\n"
                          "f 1 2 3\n"          // no group yet
                          "g top\nf 1 2 3 4\n"  // quad -> 2 triangles
                          "o lid\nf 1 5 2\n"
                          "g top\nf -1 -4 -3\n"  // negative (relative) indices
                          "f 1 1 2\n");          // degenerate, kept
  const Mesh m = load_mesh(p);
  ASSERT_EQ(m.num_faces(), 6);
  EXPECT_EQ(m.faces[0], (std::array<int, 3>{0, 1, 2}));
  EXPECT_EQ(m.faces[1], (std::array<int, 3>{0, 1, 2}));
  EXPECT_EQ(m.faces[2], (std::array<int, 3>{0, 2, 3}));
  EXPECT_EQ(m.faces[3], (std::array<int, 3>{0, 4, 1}));
  EXPECT_EQ(m.faces[4], (std::array<int, 3>{4, 1, 2}));
  EXPECT_EQ(m.faces[5], (std::array<int, 3>{0, 0, 1}));
  EXPECT_EQ(group_per_face(m), (std::vector<std::string>{"", "top", "top", "lid", "top", "top"}));
  EXPECT_EQ(m.file_face, (std::vector<int>{0, 1, 2, 3, 4, 5}));
  EXPECT_THAT(::testing::PrintToString(m.import_notes), HasSubstr("fan-triangulated 1 polygons"));
}

TEST_F(Import, ObjGroupsRoundTrip) {
  const Mesh t = tetra();
  save_mesh(t, file("t.obj"));
  const Mesh m = load_mesh(file("t.obj"));
  expect_same_corners(t, m, 1e-5);
  EXPECT_EQ(m.faces, t.faces);
  EXPECT_EQ(group_per_face(m), group_per_face(t));
}

// ---------------------------------------------------------------- PLY / OFF through OpenMesh

// Three triangles on one edge (non-manifold), a face with a repeated vertex and a
// pentagon: OpenMesh's own mesh importer would drop or re-order these.
TEST_F(Import, PlyAndOffKeepOrderOfDegenerateAndNonManifoldFaces) {
  const std::string verts = "0 0 0\n1 0 0\n0 1 0\n0 -1 0\n0 0 1\n2 2 2\n";
  const std::string faces = "3 0 1 2\n3 1 0 3\n3 0 1 4\n3 5 5 0\n5 0 1 5 2 4\n3 1 0 2\n";
  const fs::path ply = text("n.ply",
                            "ply\nformat ascii 1.0\ncomment hand-written\nelement vertex 6\nproperty float x\n"
                            "property float y\nproperty float z\nelement face 6\n"
                            "property list uchar int vertex_indices\nend_header\n" + verts + faces);
  const fs::path off = text("n.off", "OFF\n# hand-written\n6 6 0\n" + verts + faces);
  const std::vector<std::array<int, 3>> expected = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}, {5, 5, 0}, {0, 1, 5},
                                                    {0, 5, 2}, {0, 2, 4}, {1, 0, 2}};
  for (const auto& p : {ply, off}) {
    const Mesh m = load_mesh(p);
    EXPECT_EQ(m.num_vertices(), 6) << p;
    EXPECT_EQ(m.faces, expected) << p;
    EXPECT_EQ(m.corner(7, 2), Vec3(0, 1, 0));
    EXPECT_THAT(::testing::PrintToString(m.import_notes), HasSubstr("fan-triangulated 1 polygons")) << p;
  }
  // Writing such a mesh keeps every face in place too (OpenMesh's add_face refuses
  // the non-manifold and repeated-vertex faces; they get their own vertex copies).
  const Mesh m = load_mesh(ply);
  for (const char* ext : {".stl", ".obj", ".ply", ".off", ".3mf"}) {
    SCOPED_TRACE(ext);
    save_mesh(m, file(std::string("back") + ext));
    expect_same_corners(m, load_mesh(file(std::string("back") + ext)), 1e-6);
  }
}

// ---------------------------------------------------------------- the same part in every format

TEST_F(Import, SamePartThroughEveryFormat) {
  Mesh part = shapes::slab(40, 30, 3, 4);
  part.vertices[0] += Vec3(0.123456, -0.5, 0.25);  // a few non-round numbers
  for (const char* ext : {".stl", ".obj", ".ply", ".off", ".3mf"}) {
    SCOPED_TRACE(ext);
    const fs::path p = file(std::string("part") + ext);
    save_mesh(part, p);
    const Mesh m = load_mesh(p);
    expect_same_corners(part, m, 2e-5);  // float precision at 20 mm
    EXPECT_EQ(m.file_face.size(), part.faces.size());
    if (std::string(ext) == ".obj" || std::string(ext) == ".3mf") {
      EXPECT_EQ(group_per_face(m), group_per_face(part));
    }
    EXPECT_EQ(m.source_units, "mm");
  }
  // Independent route: hand-written ASCII STL of the same triangles.
  std::string stl = "solid slab\n";
  for (int f = 0; f < part.num_faces(); ++f) {
    stl += "facet normal 0 0 0\nouter loop\n";
    for (int k = 0; k < 3; ++k) {
      char line[128];
      std::snprintf(line, sizeof line, "vertex %.17g %.17g %.17g\n", part.corner(f, k).x(), part.corner(f, k).y(),
                    part.corner(f, k).z());
      stl += line;
    }
    stl += "endloop\nendfacet\n";
  }
  stl += "endsolid slab\n";
  expect_same_corners(part, load_mesh(text("hand.stl", stl)), 1e-7);
}

TEST_F(Import, SaveIsAtomicAndRejectsUnknownFormats) {
  const Mesh t = tetra();
  save_mesh(t, file("t.stl"));
  save_mesh(t, file("t.stl"));  // replaces
  int entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_)) ++entries;
  EXPECT_EQ(entries, 1);  // no temporary left behind
  expect_input_error([&] { save_mesh(t, file("t.xyz")); }, file("t.xyz"), "format");
  expect_input_error([&] { save_mesh(t, file("missing/t.stl")); }, file("missing/t.stl"), "does not exist");
}

// ---------------------------------------------------------------- units

TEST_F(Import, MetreCubeBecomesThousandMillimetres) {
  Mesh cube = shapes::box(Vec3(1, 1, 1));
  save_mesh(cube, file("cube.obj"));
  const Mesh m = load_mesh(file("cube.obj"), {LengthUnit::metre});
  const auto [lo, hi] = bounding_box(m);
  EXPECT_NEAR((hi - lo).x(), 1000, 1e-9);
  EXPECT_NEAR((hi - lo).z(), 1000, 1e-9);
  EXPECT_EQ(m.source_units, "m");
  const Mesh inch = load_mesh(file("cube.obj"), {LengthUnit::inch});
  EXPECT_NEAR(bounding_box(inch).second.x() - bounding_box(inch).first.x(), 25.4, 1e-9);
}

// A 3MF in centimetres whose build item moves the part by (1, 2, 3) cm, written by hand (tests/support/zip_package.hpp).
TEST_F(Import, ThreeMfCarriesItsUnitAndTransform) {
  const Mesh t = tetra();
  std::string vertices, triangles;
  for (const Vec3& v : t.vertices)  // millimetres written in centimetres
    vertices += "<vertex x=\"" + std::to_string(v.x() / 10) + "\" y=\"" + std::to_string(v.y() / 10) + "\" z=\"" + std::to_string(v.z() / 10) + "\"/>";
  for (const auto& f : t.faces)
    triangles += "<triangle v1=\"" + std::to_string(f[0]) + "\" v2=\"" + std::to_string(f[1]) + "\" v3=\"" + std::to_string(f[2]) + "\"/>";
  bytes("cm.3mf", test::package_3mf(R"(<?xml version="1.0" encoding="UTF-8"?>
<model unit="centimeter" xml:lang="en-US" xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">
 <resources><object id="1" name="tetra" type="model"><mesh><vertices>)" + vertices + "</vertices><triangles>" + triangles +
                                    R"(</triangles></mesh></object></resources>
 <build><item objectid="1" transform="1 0 0 0 1 0 0 0 1 1 2 3"/></build>
</model>)"));
  const Mesh m = load_mesh(file("cm.3mf"));
  EXPECT_EQ(m.source_units, "cm");
  ASSERT_EQ(m.num_faces(), t.num_faces());
  for (int f = 0; f < t.num_faces(); ++f)
    for (int k = 0; k < 3; ++k)
      EXPECT_LE((m.corner(f, k) - (t.corner(f, k) + Vec3(10, 20, 30))).norm(), 1e-4) << f << " " << k;
  // An explicit unit overrides the file's, with a note.
  const Mesh mm = load_mesh(file("cm.3mf"), {LengthUnit::millimetre});
  EXPECT_NEAR(mm.corner(0, 0).x(), 0.1 * t.corner(0, 0).x() + 1, 1e-5);
  EXPECT_THAT(::testing::PrintToString(mm.import_notes), HasSubstr("states its unit as cm"));
}

// A 3MF packed by hand (tests/support/zip_package.hpp) from hand-written XML: build-item transform (3MF
// row-vector convention, translation last) and a components object.
TEST_F(Import, ThreeMfWrittenByHand) {
  const std::string model = R"(<?xml version="1.0" encoding="UTF-8"?>
<model unit="inch" xml:lang="en-US" xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">
 <resources>
  <object id="1" name="wedge" type="model"><mesh>
   <vertices><vertex x="0" y="0" z="0"/><vertex x="1" y="0" z="0"/><vertex x="0" y="1" z="0"/><vertex x="0" y="0" z="1"/></vertices>
   <triangles><triangle v1="0" v2="2" v3="1"/><triangle v1="0" v2="1" v3="3"/><triangle v1="1" v2="2" v3="3"/><triangle v1="0" v2="3" v3="2"/></triangles>
  </mesh></object>
  <object id="2" name="assembly" type="model"><components><component objectid="1" transform="2 0 0 0 2 0 0 0 2 0 0 0"/></components></object>
 </resources>
 <build><item objectid="2" transform="1 0 0 0 1 0 0 0 1 10 0 0"/></build>
</model>)";
  bytes("hand.3mf", test::package_3mf(model));
  const Mesh m = load_mesh(file("hand.3mf"));
  EXPECT_EQ(m.source_units, "in");
  ASSERT_EQ(m.num_faces(), 4);
  EXPECT_EQ(group_per_face(m), std::vector<std::string>(4, "wedge"));
  // vertex (0,0,1) in, scaled 2x by the component, moved 10 in along x by the item
  EXPECT_LE((m.corner(1, 2) - Vec3(254, 0, 50.8)).norm(), 1e-9);
  EXPECT_LE((m.corner(0, 1) - Vec3(254, 50.8, 0)).norm(), 1e-9);
}

// ---------------------------------------------------------------- glTF

// Writes a glTF with tinygltf: one mesh (two triangles, uint16 indices) used by two
// nodes, the second translated, scaled and rotated 90° about z; optionally a point primitive only.
void write_gltf(const fs::path& path, bool binary, bool points_only = false) {
  tinygltf::Model model;
  const std::vector<float> pos = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  const std::vector<std::uint16_t> idx = {0, 1, 2, 1, 3, 2};
  tinygltf::Buffer buffer;
  buffer.data.resize(pos.size() * 4 + idx.size() * 2);
  std::memcpy(buffer.data.data(), pos.data(), pos.size() * 4);
  std::memcpy(buffer.data.data() + pos.size() * 4, idx.data(), idx.size() * 2);
  model.buffers.push_back(buffer);
  tinygltf::BufferView vpos, vidx;
  vpos.buffer = 0, vpos.byteOffset = 0, vpos.byteLength = pos.size() * 4, vpos.target = TINYGLTF_TARGET_ARRAY_BUFFER;
  vidx.buffer = 0, vidx.byteOffset = pos.size() * 4, vidx.byteLength = idx.size() * 2;
  vidx.target = TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER;
  model.bufferViews = {vpos, vidx};
  tinygltf::Accessor apos, aidx;
  apos.bufferView = 0, apos.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT, apos.count = 4, apos.type = TINYGLTF_TYPE_VEC3;
  apos.minValues = {0, 0, 0}, apos.maxValues = {1, 1, 0};
  aidx.bufferView = 1, aidx.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, aidx.count = 6;
  aidx.type = TINYGLTF_TYPE_SCALAR;
  model.accessors = {apos, aidx};
  tinygltf::Primitive prim;
  prim.attributes["POSITION"] = 0;
  prim.mode = points_only ? TINYGLTF_MODE_POINTS : TINYGLTF_MODE_TRIANGLES;
  if (!points_only) prim.indices = 1;
  tinygltf::Mesh mesh;
  mesh.name = "plate";
  mesh.primitives.push_back(prim);
  model.meshes.push_back(mesh);
  tinygltf::Node a, b, root;
  a.mesh = 0;  // unnamed node: group named after the mesh
  b.mesh = 0, b.name = "moved";
  b.translation = {0.5, 0, 0}, b.scale = {2, 2, 2};
  b.rotation = {0, 0, std::sqrt(0.5), std::sqrt(0.5)};  // 90° about z (x, y, z, w)
  root.name = "root", root.children = {1, 2};
  root.translation = {0, 0, 0.01};
  model.nodes = {root, a, b};
  tinygltf::Scene scene;
  scene.nodes = {0};
  model.scenes.push_back(scene);
  model.defaultScene = 0;
  model.asset.version = "2.0";
  tinygltf::TinyGLTF writer;
  ASSERT_TRUE(writer.WriteGltfSceneToFile(&model, path.string(), true, true, true, binary));
}

TEST_F(Import, GltfNodesTransformsGroupsAndMetres) {
  for (bool binary : {true, false}) {
    SCOPED_TRACE(binary ? "glb" : "gltf");
    const fs::path p = file(binary ? "s.glb" : "s.gltf");
    write_gltf(p, binary);
    const Mesh m = load_mesh(p);
    EXPECT_EQ(m.source_units, "m");
    ASSERT_EQ(m.num_faces(), 4);
    EXPECT_EQ(group_per_face(m), (std::vector<std::string>{"plate", "plate", "moved", "moved"}));
    // First instance: positions + root's 0.01 m lift, in mm.
    EXPECT_LE((m.corner(1, 1) - Vec3(1000, 1000, 10)).norm(), 1e-9);
    // Second: (1,0,0) scaled 2, rotated 90° about z -> (0,2,0), moved 0.5 along x, lifted 0.01.
    EXPECT_LE((m.corner(2, 1) - Vec3(500, 2000, 10)).norm(), 1e-6);
    EXPECT_LE((m.corner(3, 1) - Vec3(-1500, 2000, 10)).norm(), 1e-6);  // (1,1,0) -> (-2,2,0) + (0.5,0,0)
  }
}

// ---------------------------------------------------------------- bad input

TEST_F(Import, BadFilesAreNamed) {
  expect_input_error([&] { load_mesh(file("nope.stl")); }, file("nope.stl"), "not found");
  fs::create_directories(file("folder.stl"));
  expect_input_error([&] { load_mesh(file("folder.stl")); }, file("folder.stl"), "directory");
  const auto empty = text("empty.obj", "");
  expect_input_error([&] { load_mesh(empty); }, empty, "empty");
  const auto unknown = text("part.dae", "<collada/>");
  expect_input_error([&] { load_mesh(unknown); }, unknown, "unknown mesh format '.dae'");
}

TEST_F(Import, UnreadableFile) {
  const auto p = text("secret.stl", kAsciiStl);
  fs::permissions(p, fs::perms::none);
  if (::geteuid() == 0) GTEST_SKIP() << "running as root: permissions cannot make a file unreadable";
  expect_input_error([&] { load_mesh(p); }, p, "cannot be opened");
}

TEST_F(Import, BadBinaryStl) {
  const std::vector<std::array<Vec3, 3>> one = {{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}};
  std::string truncated = binary_stl(one, 2);
  const auto t = bytes("truncated.stl", truncated);
  expect_input_error([&] { load_mesh(t); }, t, "header");
  expect_input_error([&] { load_mesh(t); }, t, "truncated");
  // Billions of triangles claimed: rejected by size before any allocation.
  const auto huge = bytes("huge.stl", binary_stl(one, 4000000000u));
  expect_input_error([&] { load_mesh(huge); }, huge, "claims 4000000000 triangles");
  const auto tiny = bytes("tiny.stl", std::string(40, '\1'));
  expect_input_error([&] { load_mesh(tiny); }, tiny, "too short");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const auto bad = bytes("nan.stl", binary_stl({one[0], {Vec3(0, 0, 0), Vec3(nan, 0, 0), Vec3(0, 1, 0)}}));
  expect_input_error([&] { load_mesh(bad); }, bad, "facet 1, vertex 1");
  const auto inf = bytes("inf.stl", binary_stl({{Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(0, INFINITY, 0)}}));
  expect_input_error([&] { load_mesh(inf); }, inf, "facet 0, vertex 2");
}

TEST_F(Import, BadAsciiStl) {
  std::string s = kAsciiStl;
  s.replace(s.find("vertex -1 0 0"), 13, "vertex nan 0 0");
  const auto nan = text("nan.stl", s);
  expect_input_error([&] { load_mesh(nan); }, nan, "line 27 (facet 3, vertex 2)");
  const auto word = text("word.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 zero 0\n");
  expect_input_error([&] { load_mesh(word); }, word, "'zero' is not a number");
  const auto cut = text("cut.stl", kAsciiStl.substr(0, kAsciiStl.find("endfacet")));
  expect_input_error([&] { load_mesh(cut); }, cut, "ends inside a facet");
  const auto none = text("none.stl", "solid empty\nendsolid empty\n");
  expect_input_error([&] { load_mesh(none); }, none, "no faces");
}

TEST_F(Import, NonFiniteCoordinatesNameTheVertex) {
  const auto obj = text("nan.obj", "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n");
  expect_input_error([&] { load_mesh(obj); }, obj, "line 3 (vertex 3)");
  const auto ply = text("inf.ply",
                        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                        "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                        "0 0 0\n1 0 -inf\n0 1 0\n3 0 1 2\n");
  expect_input_error([&] { load_mesh(ply); }, ply, "line 11 (vertex 1)");
  const auto off = text("nan.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 NaN 0\n3 0 1 2\n");
  expect_input_error([&] { load_mesh(off); }, off, "line 5 (vertex 2)");
  // Binary PLY: the value reaches the importer and the shared check names the vertex.
  std::string bin = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
  const float v[9] = {0, 0, 0, 1, 0, 0, 0, std::numeric_limits<float>::quiet_NaN(), 0};
  bin.append(reinterpret_cast<const char*>(v), sizeof v);
  const unsigned char n3 = 3;
  const int f[3] = {0, 1, 2};
  bin.append(reinterpret_cast<const char*>(&n3), 1).append(reinterpret_cast<const char*>(f), sizeof f);
  const auto bply = bytes("nan_bin.ply", bin);
  expect_input_error([&] { load_mesh(bply); }, bply, "vertex 2");
  // glTF: a nan position.
  write_gltf(file("nan.glb"), true);
  tinygltf::Model model;
  std::string err, warn;
  tinygltf::TinyGLTF io;
  ASSERT_TRUE(io.LoadBinaryFromFile(&model, &err, &warn, file("nan.glb").string()));
  const float qnan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(model.buffers[0].data.data() + 4, &qnan, 4);
  ASSERT_TRUE(io.WriteGltfSceneToFile(&model, file("nan.glb").string(), true, true, true, true));
  expect_input_error([&] { load_mesh(file("nan.glb")); }, file("nan.glb"), "mesh 0 primitive 0, vertex 0");
}

TEST_F(Import, FaceIndexOutOfRangeNamesTheFace) {
  const auto obj = text("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\n");
  expect_input_error([&] { load_mesh(obj); }, obj, "face 2");
  const auto ply = text("range.ply",
                        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                        "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
                        "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 3\n");
  expect_input_error([&] { load_mesh(ply); }, ply, "face 1");
  const auto off = text("range.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 2 1 -1\n");
  expect_input_error([&] { load_mesh(off); }, off, "face 1");
  const auto two = text("two.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n");
  expect_input_error([&] { load_mesh(two); }, two, "face 1");
}

TEST_F(Import, MeshesWithoutFaces) {
  const auto obj = text("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  expect_input_error([&] { load_mesh(obj); }, obj, "no faces");
  const auto ply = text("points.ply",
                        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                        "element face 0\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n");
  expect_input_error([&] { load_mesh(ply); }, ply, "no faces");
  const auto cut = text("cut.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n");
  expect_input_error([&] { load_mesh(cut); }, cut, "truncated");
  const auto claim = text("claim.ply",
                          "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\nproperty float x\n"
                          "property float y\nproperty float z\nend_header\n");
  expect_input_error([&] { load_mesh(claim); }, claim, "truncated");
}

// Damaged PLY/OFF headers and list lengths crash OpenMesh's readers or make them
// allocate without bound; they are refused before OpenMesh sees the file.
TEST_F(Import, DamagedPlyAndOffStructureIsRefusedBeforeOpenMesh) {
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  const std::string faces = "element face 1\nproperty list uchar int vertex_indices\n";
  const std::string body = "0 0 0\n1 0 0\n0 1 0\n";
  struct Case {
    const char* name;
    std::string contents, expected;
  };
  const Case cases[] = {
      {"prop_first.ply", "ply\nformat ascii 1.0\nproperty float x\nelement vertex 3\n" + xyz + faces + "end_header\n" + body + "3 0 1 2\n",
       "line 3: a property before any element"},
      {"no_count.ply", "ply\nformat ascii 1.0\nelement vertex\n" + xyz + faces + "end_header\n" + body + "3 0 1 2\n",
       "line 3: damaged element line"},
      {"face_no_count.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz + "element face\nproperty list uchar int vertex_indices\nend_header\n" + body,
       "line 7: damaged element line"},
      {"face_negative.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz + "element face -1\nproperty list uchar int vertex_indices\nend_header\n" + body,
       "'-1' is not a valid element count"},
      {"list_negative.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz + faces + "end_header\n" + body + "-3 0 1 2\n",
       "line 13 (face 0): the length of list 'vertex_indices' is '-3'"},
      {"list_long.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz + faces + "end_header\n" + body + "200 0 1 2\n",
       "ends in number 0 (truncated?)"},
      {"bad_type.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float3 x\n", "line 4: damaged property line"},
      {"float_count.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz + "element face 1\nproperty list float int vertex_indices\nend_header\n",
       "line 8: damaged property line"},
      {"twice.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz + "element vertex 3\n" + xyz + "end_header\n",
       "line 7: element 'vertex' is declared twice"},
      {"empty_element.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\nend_header\n", "element 'vertex' has no properties"},
      {"no_xyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float u\nend_header\n0\n", "lacks the scalar properties x, y and z"},
      {"no_format.ply", "ply\nelement vertex 3\n" + xyz + "end_header\n" + body, "no 'format' line"},
      {"junk_header.ply", "ply\nformat ascii 1.0\nelemnt vertex 3\nend_header\n", "line 3: unknown header line 'elemnt'"},
      {"face_minus3.off", "OFF\n3 1 0\n" + body + "-3 0 1 2\n", "line 6 (face 0): a face line is 'k i1 ... ik'"},
      {"face_long.off", "OFF\n3 1 0\n" + body + "4 0 1 2\n", "line 6 (face 0)"},
      {"count_minus3.off", "OFF\n3 -3 0\n" + body, "'-3' is not a valid element count"},
      {"short_vertex.off", "OFF\n3 1 0\n0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "line 3 (vertex 0): a vertex line needs x y z"},
      {"binary.off", "OFF BINARY\n3 1 0\n", "variant of OFF is not supported"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const fs::path p = text(c.name, c.contents);
    expect_input_error([&] { load_mesh(p); }, p, c.expected);
  }
  // Binary: a negative list length in a signed count type, and one longer than the file.
  std::string bin = "ply\nformat binary_little_endian 1.0\nelement vertex 3\n" + xyz +
                    "element face 1\nproperty list int int vertex_indices\nend_header\n";
  const float v[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  bin.append(reinterpret_cast<const char*>(v), sizeof v);
  for (const int n : {-3, 1000000}) {
    SCOPED_TRACE(n);
    const int f[4] = {n, 0, 1, 2};
    const fs::path p = bytes("list.ply", bin + std::string(reinterpret_cast<const char*>(f), sizeof f));
    expect_input_error([&] { load_mesh(p); }, p, n < 0 ? "face 0: the length of list 'vertex_indices' is -3" : "(truncated?)");
  }
}

// OpenMesh's OFF reader takes the header from the first line only and then reads
// the counts into variables it never initialised: an OFF whose first line is a
// comment or blank added faces without bound (fuzz_off found it). It also read a
// face's colour as the next face's length. OFF is now read by clearfit itself.
TEST_F(Import, OffWithLeadingCommentAndFaceColoursIsReadAsWritten) {
  const std::string body = "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2 4000000000 0 0\n3 0 3 1 0.5 0.5 0.5 1\n";
  for (const std::string head : {"# written by hand\nCOFF\n4 2 0\n", "\nOFF\n4 2 0\n", "OFF 4 2 0\n"}) {
    SCOPED_TRACE(head);
    const fs::path p = text("c.off", head + body);
    const Mesh m = load_mesh(p);
    EXPECT_EQ(m.num_vertices(), 4);
    EXPECT_EQ(m.faces, (std::vector<std::array<int, 3>>{{0, 1, 2}, {0, 3, 1}}));
    EXPECT_EQ(m.corner(1, 1), Vec3(0, 0, 1));
  }
  const fs::path bad = text("i.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2.5\n");
  expect_input_error([&] { load_mesh(bad); }, bad, "line 6 (face 0): '2.5' is not a vertex index");
}

// Every input the fuzzers found (fuzz/regressions/FORMAT/, a crash, a leak or a
// timeout once) is read or refused with an InputError naming the file, and nothing else.
TEST_F(Import, FuzzRegressionInputsAreReadOrRefused) {
  const fs::path root = fs::path(CLEARFIT_TEST_DATA_DIR) / ".." / ".." / "fuzz" / "regressions";
  int inputs = 0;
  for (const char* format : {"stl", "obj", "ply", "off", "3mf", "gltf", "glb"}) {
    if (!fs::is_directory(root / format)) continue;
    for (const auto& entry : fs::directory_iterator(root / format)) {
      SCOPED_TRACE(entry.path().string());
      const fs::path p = file(entry.path().filename().string() + "." + format);
      fs::copy_file(entry.path(), p, fs::copy_options::overwrite_existing);
      ++inputs;
      try {
        load_mesh(p);
      } catch (const InputError& e) {
        EXPECT_EQ(e.file(), p.string()) << e.what();
      }
    }
  }
  EXPECT_GT(inputs, 0) << "no regression inputs under " << root;
}

TEST_F(Import, ThreeMfWithoutMeshAndBroken3mf) {
  const auto junk = text("junk.3mf", "this is not a zip package");
  expect_input_error([&] { load_mesh(junk); }, junk, "lib3mf could not read it");
  bytes("empty.3mf", test::package_3mf(R"(<?xml version="1.0" encoding="UTF-8"?>
<model unit="millimeter" xml:lang="en-US" xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02"><resources/><build/></model>)"));
  expect_input_error([&] { load_mesh(file("empty.3mf")); }, file("empty.3mf"), "no mesh object");
}

// A 3MF's zip entries are checked before lib3mf reads them: the package written byte by byte
// (tests/support/zip_package.hpp) with honest sizes reads, stored and deflated alike; the same package
// whose model entry's headers lie about its unpacked size is refused naming the file and the entry.
TEST_F(Import, ThreeMfZipEntrySizesAreBoundedBeforeLib3mf) {
  for (bool deflate : {false, true}) {
    const Mesh m = load_mesh(bytes(deflate ? "deflated.3mf" : "stored.3mf", test::tetra_3mf(deflate)));
    EXPECT_EQ(m.num_vertices(), 4);
    EXPECT_EQ(m.num_faces(), 4);
  }
  const std::string entry = "zip entry '3D/3dmodel.model'";
  const std::uint32_t model_size = static_cast<std::uint32_t>(test::tetra_3mf_entries().back().data.size());
  struct Lie {
    const char* file;
    bool deflate;
    std::uint32_t declared;
    std::string defect;
  };
  for (const Lie& lie : {Lie{"huge_stored.3mf", false, 0xFFFFFFF0u, "declares 4294967280 bytes unpacked from " + std::to_string(model_size)},
                         Lie{"huge_deflated.3mf", true, 0xFFFFFFF0u, "more than deflate can unpack"},
                         Lie{"small_deflated.3mf", true, 100u, "unpacks to more than the 100 bytes"},
                         Lie{"large_deflated.3mf", true, model_size + 1000, "unpacks to " + std::to_string(model_size) + " bytes"}}) {
    SCOPED_TRACE(lie.file);
    const fs::path p = bytes(lie.file, test::tetra_3mf(lie.deflate, lie.declared));
    expect_input_error([&] { load_mesh(p); }, p, entry);
    expect_input_error([&] { load_mesh(p); }, p, lie.defect);
  }
}

TEST_F(Import, GltfWithoutTriangles) {
  write_gltf(file("points.glb"), true, /*points_only=*/true);
  expect_input_error([&] { load_mesh(file("points.glb")); }, file("points.glb"), "no triangles");
  const auto junk = text("junk.gltf", "{ not json");
  expect_input_error([&] { load_mesh(junk); }, junk, "tinygltf could not read it");
}

}  // namespace
}  // namespace clearfit
