// The heatmap .glb: every file passes the Khronos glTF validator (node +
// web/node_modules/gltf-validator through tests/tools/validate_gltf.mjs), and
// reads back with tinygltf to exactly what was put in: colours are the
// colormap in linear light, scalars are NaN-free, uvs land on the texels that
// hold the vertex's value.
#include <clearfit/fit/chart_field.hpp>
#include <clearfit/fit/srgb.hpp>
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/reports/colormap.hpp>
#include <clearfit/reports/heatmap_glb.hpp>

#include "../support/glb_read.hpp"

#include <gtest/gtest.h>
#include <tiny_gltf.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

namespace fs = std::filesystem;

namespace clearfit {
namespace {

const fs::path kRepo = fs::path(CLEARFIT_TEST_DATA_DIR).parent_path().parent_path();

// Runs the validator script on `file`; returns its exit code and fills `log`.
int run_validator(const fs::path& file, std::string& log) {
  const fs::path out = file.string() + ".validator.txt";
  const std::string cmd = "node \"" + (kRepo / "tests/tools/validate_gltf.mjs").string() + "\" \"" +
                          file.string() + "\" > \"" + out.string() + "\" 2>&1";
  const int status = std::system(cmd.c_str());
  std::ifstream in(out);
  std::stringstream ss;
  ss << in.rdbuf();
  log = ss.str();
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

class HeatmapGlb : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    ASSERT_TRUE(fs::exists(kRepo / "web/node_modules/gltf-validator/package.json"))
        << "the Khronos glTF validator is not installed in " << (kRepo / "web/node_modules")
        << ": run scripts/bootstrap.sh deps (it runs npm ci --prefix web)";
    ASSERT_EQ(std::system("node --version > /dev/null 2>&1"), 0)
        << "node is not on PATH: run scripts/bootstrap.sh deps";
  }
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("clearfit_heatmap_glb_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure() && std::getenv("CLEARFIT_KEEP_TEST_OUTPUT") == nullptr) fs::remove_all(dir_);
  }
  fs::path dir_;
};

// A part with its contact chart, a pressure field on the chart grid and the
// per-vertex samples of it.
struct Case {
  Mesh mesh;
  ContactSurface contact;
  Chart chart;
  ChartField pressure;  // kPa
  ChartField blanch;    // signal: 0.002 per kPa
  std::vector<float> pressure_at_vertex, blanch_at_vertex;
};

// Two Gaussian blobs on the chart (peaks 20 and 12 kPa); texels with u beyond
// `unseen_u_fraction` of the chart's width are NaN (not seen).
Case make_case(Mesh mesh, double texel_mm, double unseen_u_fraction) {
  Case c;
  c.mesh = std::move(mesh);
  ContactSelector sel;
  sel.group = "contact";
  c.contact = select_contact(c.mesh, sel);
  c.chart = compute_chart(c.mesh, c.contact);
  c.pressure.grid = ChartGrid::covering(c.chart.uv_min, c.chart.uv_max, texel_mm);
  const ChartGrid& g = c.pressure.grid;
  const Vec2 size = c.chart.uv_max - c.chart.uv_min;
  const Vec2 a = c.chart.uv_min + Vec2(0.3, 0.4).cwiseProduct(size),
             b = c.chart.uv_min + Vec2(0.6, 0.7).cwiseProduct(size);
  const double s = 0.15 * size.minCoeff();
  c.pressure.value.resize(g.size());
  for (int j = 0; j < g.height; ++j) {
    for (int i = 0; i < g.width; ++i) {
      Vec2 uv = g.uv(i, j);
      double p = 20 * std::exp(-(uv - a).squaredNorm() / (2 * s * s)) +
                 12 * std::exp(-(uv - b).squaredNorm() / (2 * s * s));
      bool unseen = uv[0] > c.chart.uv_min[0] + unseen_u_fraction * size[0];
      c.pressure.value[g.index(i, j)] = unseen ? NAN : static_cast<float>(p);
    }
  }
  c.blanch = c.pressure;
  for (float& y : c.blanch.value) y *= 0.002f;
  c.pressure_at_vertex = sample_at_vertices(c.pressure, c.chart);
  for (float p : c.pressure_at_vertex) c.blanch_at_vertex.push_back(std::isnan(p) ? NAN : 0.002f * p);
  return c;
}

HeatmapInput input_for(const Case& c) {
  HeatmapInput in;
  in.mesh = &c.mesh;
  in.chart = &c.chart;
  in.values = c.pressure_at_vertex;
  in.scalars = {{"_PRESSURE_KPA", c.pressure_at_vertex}, {"_BLANCH", c.blanch_at_vertex}};
  in.texture = &c.pressure;
  in.range_lo = 0;
  in.range_hi = 25;
  in.extras = {{"report", "report.json"}};
  return in;
}

// Validates, reads back and checks the file written for `in`.
void check_heatmap(const HeatmapInput& in, const fs::path& path, std::size_t hotspots) {
  std::string log;
  EXPECT_EQ(run_validator(path, log), 0) << log;
  const tinygltf::Model m = test::load_glb(path);
  const Colormap& cm = Colormap::get(in.colormap);

  // Extras on the asset.
  const tinygltf::Value& info = m.asset.extras.Get("clearfit");
  ASSERT_TRUE(info.IsObject());
  EXPECT_EQ(info.Get("schema").Get<std::string>(), "clearfit.heatmap/1");
  EXPECT_EQ(info.Get("quantity").Get<std::string>(), in.quantity);
  EXPECT_EQ(info.Get("colormap").Get<std::string>(), in.colormap);
  EXPECT_EQ(info.Get("unit").Get<std::string>(), in.unit);
  EXPECT_DOUBLE_EQ(info.Get("range").Get(0).GetNumberAsDouble(), in.range_lo);
  EXPECT_DOUBLE_EQ(info.Get("range").Get(1).GetNumberAsDouble(), in.range_hi);
  EXPECT_EQ(info.Get("report").Get<std::string>(), "report.json");
  EXPECT_EQ(m.extensionsUsed, std::vector<std::string>{"KHR_materials_unlit"});
  for (const auto& mat : m.materials) EXPECT_TRUE(mat.extensions.count("KHR_materials_unlit")) << mat.name;

  // Scenes: the textured one first when there is a texture; the part node scaled mm → m.
  ASSERT_EQ(m.scenes.size(), in.texture ? 2u : 1u);
  EXPECT_EQ(m.defaultScene, 0);
  EXPECT_EQ(m.scenes.back().name, "vertex_colors");
  const tinygltf::Node& part = m.nodes.at(m.scenes.back().nodes.at(0));
  EXPECT_EQ(part.scale, std::vector<double>(3, 0.001));
  EXPECT_EQ(m.scenes.back().nodes.size(), hotspots > 0 ? 2u : 1u);
  if (hotspots > 0) {
    EXPECT_EQ(m.nodes.at(m.scenes.back().nodes.at(1)).children.size(), hotspots);
  }

  // The vertex-colour mesh: all attributes on every primitive, one vertex set.
  const tinygltf::Mesh& vmesh = m.meshes.at(part.mesh);
  ASSERT_FALSE(vmesh.primitives.empty());
  const auto& attr = vmesh.primitives[0].attributes;
  for (const char* name :
       {"POSITION", "NORMAL", "COLOR_0", "TEXCOORD_0", "_SEEN", "_PRESSURE_KPA", "_BLANCH"}) {
    ASSERT_TRUE(attr.count(name)) << name;
  }
  const std::size_t n = m.accessors.at(attr.at("POSITION")).count;
  for (const auto& [name, acc] : attr) EXPECT_EQ(m.accessors.at(acc).count, n) << name;
  EXPECT_GE(n, static_cast<std::size_t>(in.mesh->num_vertices()));
  std::size_t triangles = 0;
  for (const auto& p : vmesh.primitives) triangles += m.accessors.at(p.indices).count / 3;
  EXPECT_EQ(triangles, in.mesh->faces.size());

  const auto pos = test::read_accessor<float>(m, attr.at("POSITION"), 3);
  const auto col = test::read_accessor<float>(m, attr.at("COLOR_0"), 3);
  const auto uv = test::read_accessor<float>(m, attr.at("TEXCOORD_0"), 2);
  const auto seen = test::read_accessor<float>(m, attr.at("_SEEN"), 1);
  const auto kpa = test::read_accessor<float>(m, attr.at("_PRESSURE_KPA"), 1);
  const auto blanch = test::read_accessor<float>(m, attr.at("_BLANCH"), 1);

  // Which mesh vertex each output vertex came from (positions are unique in these shapes).
  std::map<std::array<float, 3>, int> vertex_at;
  for (int v = 0; v < in.mesh->num_vertices(); ++v) {
    vertex_at[{static_cast<float>(in.mesh->vertices[v][0]), static_cast<float>(in.mesh->vertices[v][1]),
               static_cast<float>(in.mesh->vertices[v][2])}] = v;
  }
  ASSERT_EQ(vertex_at.size(), static_cast<std::size_t>(in.mesh->num_vertices()));

  const tinygltf::Image* image = m.images.empty() ? nullptr : &m.images[0];
  if (in.texture) {
    ASSERT_NE(image, nullptr);
    EXPECT_EQ(image->width, in.texture->grid.width);
    EXPECT_EQ(image->height, in.texture->grid.height);
    EXPECT_EQ(image->mimeType, "image/png");
  }
  int seen_count = 0, texel_checks = 0;
  const Eigen::Vector3f grey = cm.no_data_linear();
  for (std::size_t o = 0; o < n; ++o) {
    const int v = vertex_at.at({pos[3 * o], pos[3 * o + 1], pos[3 * o + 2]});
    const Eigen::Vector3f c(col[3 * o], col[3 * o + 1], col[3 * o + 2]);
    if (seen[o] == 1.0f) {
      ++seen_count;
      const float value = in.values[v];
      ASSERT_TRUE(std::isfinite(value));
      const Eigen::Vector3f expected = cm.linear(normalise_to_range(value, in.range_lo, in.range_hi));
      EXPECT_LT((c - expected).cwiseAbs().maxCoeff(), 1e-6) << "vertex " << v << " value " << value;
      EXPECT_EQ(kpa[o], in.scalars[0].values[v]);
      EXPECT_EQ(blanch[o], in.scalars[1].values[v]);
      // The texel under the vertex's uv holds (nearly) the vertex's value.
      if (image && uv[2 * o] > 0.02 && uv[2 * o] < 0.98 && uv[2 * o + 1] > 0.02 && uv[2 * o + 1] < 0.98) {
        int i = static_cast<int>(uv[2 * o] * image->width),
            j = static_cast<int>(uv[2 * o + 1] * image->height);
        const unsigned char* px =
            &image->image[(static_cast<std::size_t>(j) * image->width + i) * image->component];
        float texel = in.texture->value[in.texture->grid.index(i, j)];
        if (std::isfinite(texel)) {
          Rgb8 e = cm.srgb8(normalise_to_range(texel, in.range_lo, in.range_hi));
          EXPECT_EQ(px[0], e.r);
          EXPECT_EQ(px[1], e.g);
          EXPECT_EQ(px[2], e.b);
          EXPECT_NEAR(texel, value, 0.05 * (in.range_hi - in.range_lo) + 1e-3)
              << "uv does not land on the vertex";
          ++texel_checks;
        }
      }
    } else {
      EXPECT_EQ(seen[o], 0.0f);
      EXPECT_LT((c - grey).cwiseAbs().maxCoeff(), 1e-6);
      EXPECT_EQ(kpa[o], 0.0f);
      EXPECT_EQ(blanch[o], 0.0f);
    }
  }
  EXPECT_GT(seen_count, 0);
  if (in.texture) {
    EXPECT_GT(texel_checks, 0);
  }
}

TEST_F(HeatmapGlb, BumpPlateFullySeenWithHotspots) {
  Case c = make_case(shapes::bump_plate(30, 20, 3, 12, 3, 2, 7), 0.25, 2.0);
  HeatmapInput in = input_for(c);
  in.hotspots = {{1, Vec3(-5, 0, 0), "peak 20 kPa"}, {2, Vec3(4, 3, 0), "peak 12 kPa"}};
  write_heatmap_glb(in, dir_ / "bump.glb");
  check_heatmap(in, dir_ / "bump.glb", 2);
}

TEST_F(HeatmapGlb, BumpPlateWithUnseenVerticesAndNoHotspots) {
  Case c = make_case(shapes::bump_plate(30, 20, 3, 12, 2, 1.5, 3), 0.25, 0.6);
  HeatmapInput in = input_for(c);
  int unseen = 0;
  for (int v = 0; v < c.mesh.num_vertices(); ++v)
    unseen += c.chart.uv[v].allFinite() && std::isnan(in.values[v]);
  EXPECT_GT(unseen, 10);
  write_heatmap_glb(in, dir_ / "bump_unseen.glb");
  check_heatmap(in, dir_ / "bump_unseen.glb", 0);
}

TEST_F(HeatmapGlb, CylindricalShellSignal) {
  Case c = make_case(shapes::cylindrical_shell(30, 33, 120, 25, 48, 10), 0.3, 0.8);
  HeatmapInput in = input_for(c);
  in.values = c.blanch_at_vertex;
  in.texture = &c.blanch;
  in.quantity = "signal";
  in.unit = "";
  in.range_lo = 0;
  in.range_hi = 0.05;
  in.hotspots = {{1, Vec3(0, 0, 30), "signal 0.04"}};
  write_heatmap_glb(in, dir_ / "shell.glb");
  check_heatmap(in, dir_ / "shell.glb", 1);
}

TEST_F(HeatmapGlb, WithoutTextureOneScene) {
  Case c = make_case(shapes::bump_plate(20, 20, 2, 8, 1, 1, 11), 0.5, 0.5);
  HeatmapInput in = input_for(c);
  in.texture = nullptr;
  write_heatmap_glb(in, dir_ / "plain.glb");
  check_heatmap(in, dir_ / "plain.glb", 0);
  EXPECT_TRUE(test::load_glb(dir_ / "plain.glb").images.empty());
}

TEST_F(HeatmapGlb, DifferenceUsesTheDivergingMapSymmetrically) {
  Case c = make_case(shapes::bump_plate(30, 20, 3, 12, 2, 1.5, 5), 0.25, 0.9);
  ChartField diff = c.pressure;
  for (float& v : diff.value) v = v - 6;  // negative and positive
  HeatmapInput in = input_for(c);
  in.texture = &diff;
  in.values = sample_at_vertices(diff, c.chart);
  in.scalars = {{"_PRESSURE_KPA", in.values}, {"_BLANCH", c.blanch_at_vertex}};
  in.quantity = "pressure_difference_kpa";
  write_difference_glb(in, 0, dir_ / "diff.glb");
  const tinygltf::Model m = test::load_glb(dir_ / "diff.glb");
  const tinygltf::Value& info = m.asset.extras.Get("clearfit");
  EXPECT_EQ(info.Get("colormap").Get<std::string>(), "coolwarm");
  const double hi = info.Get("range").Get(1).GetNumberAsDouble();
  EXPECT_DOUBLE_EQ(info.Get("range").Get(0).GetNumberAsDouble(), -hi);
  EXPECT_NEAR(hi, 14.0, 0.5);  // peak 20 − 6, from the texture's finite values
  in.colormap = "coolwarm";
  in.range_lo = -hi;
  in.range_hi = hi;
  check_heatmap(in, dir_ / "diff.glb", 0);
}

TEST_F(HeatmapGlb, ValidatorRejectsABrokenFile) {
  // POSITION without min/max and a non-unit normal: the validator must complain,
  // so the checks above can fail.
  tinygltf::Model m;
  m.asset.version = "2.0";
  std::vector<float> data = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 2, 0, 0, 2};
  m.buffers.resize(1);
  m.buffers[0].data.resize(data.size() * 4);
  std::memcpy(m.buffers[0].data.data(), data.data(), data.size() * 4);
  for (int k = 0; k < 2; ++k) {
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = 36 * k;
    view.byteLength = 36;
    view.target = TINYGLTF_TARGET_ARRAY_BUFFER;
    m.bufferViews.push_back(view);
    tinygltf::Accessor acc;
    acc.bufferView = k;
    acc.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    acc.count = 3;
    acc.type = TINYGLTF_TYPE_VEC3;
    m.accessors.push_back(acc);
  }
  tinygltf::Primitive p;
  p.attributes = {{"POSITION", 0}, {"NORMAL", 1}};
  tinygltf::Mesh mesh;
  mesh.primitives.push_back(p);
  m.meshes.push_back(mesh);
  tinygltf::Node node;
  node.mesh = 0;
  m.nodes.push_back(node);
  tinygltf::Scene scene;
  scene.nodes = {0};
  m.scenes.push_back(scene);
  const fs::path path = dir_ / "broken.glb";
  ASSERT_TRUE(tinygltf::TinyGLTF().WriteGltfSceneToFile(&m, path.string(), true, true, false, true));
  std::string log;
  EXPECT_EQ(run_validator(path, log), 1) << log;
  EXPECT_NE(log.find("ACCESSOR_VECTOR3_NON_UNIT"), std::string::npos) << log;
}

TEST_F(HeatmapGlb, BadInputIsRefusedAndNothingIsWritten) {
  Case c = make_case(shapes::bump_plate(20, 20, 2, 4, 1, 1, 2), 0.5, 2.0);
  HeatmapInput in = input_for(c);
  in.values.pop_back();
  EXPECT_THROW(write_heatmap_glb(in, dir_ / "bad.glb"), std::invalid_argument);
  in = input_for(c);
  in.scalars[0].name = "PRESSURE";
  EXPECT_THROW(write_heatmap_glb(in, dir_ / "bad.glb"), std::invalid_argument);
  in = input_for(c);
  in.extras["schema"] = "mine";
  EXPECT_THROW(write_heatmap_glb(in, dir_ / "bad.glb"), std::invalid_argument);
  in = input_for(c);
  in.range_hi = in.range_lo;
  EXPECT_THROW(write_heatmap_glb(in, dir_ / "bad.glb"), std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir_ / "bad.glb"));
  in = input_for(c);
  EXPECT_ANY_THROW(write_heatmap_glb(in, dir_ / "no_such_folder" / "x.glb"));
}

}  // namespace
}  // namespace clearfit
