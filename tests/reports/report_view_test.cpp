// The 3D view's triangle budget (HtmlReportOptions::max_view_triangles):
// simplify_triangles keeps original vertices, meets the budget, keeps the rim
// and stays close to the original surface (vertical rays onto the simplified
// height field, an upper bound of the distance); report.html embeds a
// simplified, valid glb whose vertices carry the original attributes.
// CLEARFIT_VIEW_BENCH=1 also times the 1M-triangle case (skipped otherwise).
#include <clearfit/reports/simplify.hpp>

#include <gtest/gtest.h>
#include <tiny_gltf.h>
#include <unistd.h>
#include <clearfit/geometry/ray_index.hpp>
#include <clearfit/reports/report_html.hpp>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <numeric>
#include <random>
#include <set>
#include <sstream>

#include "../support/glb_read.hpp"
#include "report_fixture.hpp"

namespace clearfit {
namespace {

namespace fs = std::filesystem;
using report_test::FixtureOptions;
using report_test::make_assessment_folder;
using reports::simplify_triangles;
using test::embedded_glb;
using test::parse_glb;

const fs::path kRepo = fs::path(CLEARFIT_TEST_DATA_DIR).parent_path().parent_path();

// A height field over [0, 40] x [0, 40] mm with bumps and waves, n x n quads.
struct Grid {
  std::vector<float> position;
  std::vector<std::uint32_t> triangles;
  int n;
  static double height(double x, double y) {
    return 3 * std::exp(-((x - 15) * (x - 15) + (y - 22) * (y - 22)) / (2 * 36.0)) +
           0.8 * std::sin(x / 4) * std::cos(y / 6);
  }
  explicit Grid(int n_) : n(n_) {
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) {
        const double x = 40.0 * i / n, y = 40.0 * j / n;
        position.insert(position.end(), {float(x), float(y), float(height(x, y))});
      }
    auto v = [&](int i, int j) { return std::uint32_t(j * (n + 1) + i); };
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        triangles.insert(triangles.end(),
                         {v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j), v(i + 1, j + 1), v(i, j + 1)});
  }
  bool on_rim(std::uint32_t k) const {
    const int i = k % (n + 1), j = k / (n + 1);
    return i == 0 || j == 0 || i == n || j == n;
  }
};

Mesh to_mesh(const std::vector<float>& position, const std::vector<std::uint32_t>& triangles) {
  Mesh m;
  for (std::size_t v = 0; v < position.size() / 3; ++v)
    m.vertices.emplace_back(position[3 * v], position[3 * v + 1], position[3 * v + 2]);
  for (std::size_t t = 0; t < triangles.size() / 3; ++t)
    m.faces.push_back({int(triangles[3 * t]), int(triangles[3 * t + 1]), int(triangles[3 * t + 2])});
  m.file_face.resize(m.faces.size());
  std::iota(m.file_face.begin(), m.file_face.end(), 0);
  return m;
}

TEST(SimplifyTriangles, HeightFieldMeetsBudgetKeepsRimAndStaysClose) {
  const Grid grid(224);  // 100,352 triangles (ASan runs this too)
  const std::size_t budget = 25000;
  const auto s = simplify_triangles(grid.position, grid.triangles, budget);
  const std::size_t nt = s.triangles.size() / 3, nv = grid.position.size() / 3;
  EXPECT_LE(nt, budget);
  EXPECT_GE(nt, 0.9 * budget);
  ASSERT_EQ(s.source_face.size(), nt);
  EXPECT_EQ(std::set<std::uint32_t>(s.source_face.begin(), s.source_face.end()).size(), nt);
  std::vector<char> used(nv, 0);
  for (std::size_t t = 0; t < nt; ++t) {
    const std::uint32_t a = s.triangles[3 * t], b = s.triangles[3 * t + 1], c = s.triangles[3 * t + 2];
    ASSERT_LT(std::max({a, b, c}), nv);  // original vertices only
    ASSERT_TRUE(a != b && b != c && a != c) << "degenerate triangle " << t;
    ASSERT_LT(s.source_face[t], grid.triangles.size() / 3);
    used[a] = used[b] = used[c] = 1;
    // Orientation kept, nothing flipped: every face still looks up (+z).
    const Eigen::Vector3f p0(&grid.position[3 * a]), p1(&grid.position[3 * b]), p2(&grid.position[3 * c]);
    ASSERT_GT((p1 - p0).cross(p2 - p0).z(), 0) << "face " << t << " turned over";
  }
  for (std::uint32_t v = 0; v < nv; ++v)
    if (grid.on_rim(v)) {
      ASSERT_TRUE(used[v]) << "rim vertex " << v << " was collapsed";
    }

  // Points sampled on the original triangles, dropped vertically onto the
  // simplified surface: |Δz| bounds their distance to it from above.
  const Mesh simplified = to_mesh(grid.position, s.triangles);
  const auto index = make_ray_index(simplified);
  const unsigned seed = 20261122;
  std::printf("sampling seed %u\n", seed);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Ray> rays;
  std::vector<double> z;
  for (int k = 0; k < 20000; ++k) {
    const std::size_t t = std::uniform_int_distribution<std::size_t>(0, grid.triangles.size() / 3 - 1)(rng);
    double a = u(rng), b = u(rng);
    if (a + b > 1) a = 1 - a, b = 1 - b;
    Vec3 p = Vec3::Zero();
    const double w[3] = {1 - a - b, a, b};
    for (int c = 0; c < 3; ++c)
      for (int d = 0; d < 3; ++d) p[d] += w[c] * grid.position[3 * grid.triangles[3 * t + c] + d];
    rays.push_back({Vec3(p.x(), p.y(), 100), Vec3(0, 0, -1)});
    z.push_back(p.z());
  }
  std::vector<RayHit> hits(rays.size());
  index->intersect(rays, hits);
  double worst = 0;
  for (std::size_t k = 0; k < rays.size(); ++k) {
    ASSERT_TRUE(hits[k]) << "the simplified surface has a hole under sample " << k;
    worst = std::max(worst, std::abs(hits[k].point.z() - z[k]));
  }
  const double diagonal = std::sqrt(40.0 * 40 * 2 + 5.0 * 5);
  std::printf("%zu -> %zu triangles, worst vertical deviation %.4f mm (diagonal %.1f mm)\n",
              grid.triangles.size() / 3, nt, worst, diagonal);
  EXPECT_LT(worst, 0.001 * diagonal);  // 0.1 %: ten times stricter than a view needs
}

// A flat plate (zero quadric error everywhere): the colours decide. A colour
// jump (grey | colormap at x = 10 mm) keeps every vertex on both sides of it,
// and a colour blob keeps more vertices than an even region of the same size.
TEST(SimplifyTriangles, FlatPlateFollowsTheColours) {
  Grid grid(100);  // 20,000 triangles
  const std::size_t nv = grid.position.size() / 3;
  std::vector<float> colour(3 * nv);
  auto blob = [](double x, double y) {
    return std::exp(-((x - 28) * (x - 28) + (y - 20) * (y - 20)) / (2 * 9.0));
  };
  for (std::size_t v = 0; v < nv; ++v) {
    float& z = grid.position[3 * v + 2];
    z = 0;
    const double x = grid.position[3 * v], y = grid.position[3 * v + 1];
    const Eigen::Vector3f c =
        x < 10 ? Eigen::Vector3f(0.5f, 0.5f, 0.5f)
               : Eigen::Vector3f(0.1f, 0.f, 0.3f) + float(blob(x, y)) * Eigen::Vector3f(0.8f, 0.9f, -0.2f);
    for (int k = 0; k < 3; ++k) colour[3 * v + k] = c[k];
  }
  // Kept vertices in the blob and in an even disc of the same size (blob < 1e-5 there).
  auto count = [&](const reports::SimplifiedTriangles& s, bool check_jump) {
    std::vector<char> used(nv, 0);
    for (std::uint32_t i : s.triangles) used[i] = 1;
    std::pair<int, int> n{0, 0};
    for (std::uint32_t v = 0; v < nv; ++v) {
      const double x = grid.position[3 * v], y = grid.position[3 * v + 1];
      if (check_jump && std::abs(x - 10) < 0.3) {
        EXPECT_TRUE(used[v]) << "vertex " << v << " beside the colour jump was removed";
      }
      if (!used[v]) continue;
      if (std::hypot(x - 28, y - 20) < 6) ++n.first;
      if (std::hypot(x - 20, y - 8) < 6) ++n.second;
    }
    return n;
  };
  const auto s = simplify_triangles(grid.position, grid.triangles, 4000, colour);
  EXPECT_LE(s.triangles.size() / 3, 4000u);
  EXPECT_GE(s.triangles.size() / 3, 3600u);
  const auto [blob_kept, even_kept] = count(s, true);
  const auto [blob_plain, even_plain] = count(simplify_triangles(grid.position, grid.triangles, 4000), false);
  std::printf("kept vertices in the blob / an even disc: %d / %d with colours, %d / %d without\n", blob_kept,
              even_kept, blob_plain, even_plain);
  EXPECT_GT(blob_kept, 2 * even_kept);
  EXPECT_LT(blob_plain, 1.5 * even_plain);  // the geometry alone does not tell them apart
}

TEST(SimplifyTriangles, WithinBudgetIsUnchanged) {
  const Grid grid(20);  // 800 triangles
  for (std::size_t budget : {std::size_t(800), std::size_t(5000)}) {
    const auto s = simplify_triangles(grid.position, grid.triangles, budget);
    EXPECT_EQ(s.triangles, grid.triangles);
    ASSERT_EQ(s.source_face.size(), 800u);
    for (std::uint32_t t = 0; t < 800; ++t) EXPECT_EQ(s.source_face[t], t);
  }
  const std::vector<std::uint32_t> bad = {0, 1, 99999};
  EXPECT_THROW(simplify_triangles(grid.position, bad, 10), std::invalid_argument);
}

// Triangles OpenMesh refuses (a third face on an edge, repeated corners) come
// back as they were; the rest is still simplified.
TEST(SimplifyTriangles, RefusedTrianglesAreKept) {
  Grid grid(40);  // 3200 triangles
  const std::uint32_t extra = grid.position.size() / 3;
  grid.position.insert(grid.position.end(), {20, 20, 10});
  const std::uint32_t a = grid.triangles[0], b = grid.triangles[1];  // an edge with one face already
  const std::vector<std::uint32_t> fin = {a, b, extra}, fin2 = {b, a, extra}, degenerate = {5, 5, 6};
  for (const auto* t : {&fin, &fin2, &degenerate})
    grid.triangles.insert(grid.triangles.end(), t->begin(), t->end());
  const std::size_t n = grid.triangles.size() / 3;
  const auto s = simplify_triangles(grid.position, grid.triangles, 1000);
  EXPECT_LE(s.triangles.size() / 3, 1000u);
  EXPECT_GE(s.triangles.size() / 3, 900u);
  int found = 0;
  for (std::size_t t = 0; t < s.source_face.size(); ++t)
    if (s.source_face[t] >= n - 3) {
      ++found;
      for (int k = 0; k < 3; ++k) EXPECT_EQ(s.triangles[3 * t + k], grid.triangles[3 * s.source_face[t] + k]);
    }
  EXPECT_GE(found, 2);  // the degenerate one and at least one fin (OpenMesh may take one of the two)
}

// ---- report.html end to end ----

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::size_t triangle_count(const tinygltf::Model& m) {
  std::size_t n = 0;
  for (const tinygltf::Mesh& mesh : m.meshes)
    for (const tinygltf::Primitive& p : mesh.primitives) n += m.accessors.at(p.indices).count / 3;
  return n;
}

// Per vertex, the values of every attribute of the primitive that has COLOR_0 (name order).
std::vector<std::vector<float>> vertex_records(const tinygltf::Model& m) {
  const tinygltf::Primitive* prim = nullptr;
  for (const tinygltf::Mesh& mesh : m.meshes)
    for (const tinygltf::Primitive& p : mesh.primitives)
      if (p.attributes.count("COLOR_0")) prim = &p;
  if (!prim) return {};
  std::vector<std::vector<float>> out(m.accessors.at(prim->attributes.at("POSITION")).count);
  for (const auto& [name, index] : prim->attributes) {
    const std::vector<float> f = test::read_accessor<float>(m, index, tinygltf::GetNumComponentsInType(m.accessors[index].type));
    const std::size_t k = f.size() / out.size();
    for (std::size_t v = 0; v < out.size(); ++v) out[v].insert(out[v].end(), &f[v * k], &f[v * k] + k);
  }
  return out;
}

int run_validator(const fs::path& file, std::string& log) {
  const fs::path out = file.string() + ".validator.txt";
  const std::string cmd = "node \"" + (kRepo / "tests/tools/validate_gltf.mjs").string() + "\" \"" +
                          file.string() + "\" > \"" + out.string() + "\" 2>&1";
  const int status = std::system(cmd.c_str());
  log = slurp(out);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

class ReportView : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("clearfit_report_view_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
  }
  void TearDown() override {
    if (!HasFailure() && !std::getenv("CLEARFIT_KEEP_TEST_OUTPUT")) fs::remove_all(dir_);
  }
  fs::path dir_;
};

TEST_F(ReportView, BigHeatmapIsSimplifiedForThePageOnly) {
  FixtureOptions o;
  o.n = 80;  // 26,240 triangles
  make_assessment_folder(dir_, o);
  const std::string heatmap = slurp(dir_ / "heatmap.glb");
  const tinygltf::Model original = parse_glb(heatmap);
  const std::size_t n = triangle_count(original) / 2;  // each scene's mesh draws every face once
  ASSERT_EQ(n, 26240u);

  reports::HtmlReportOptions full_options;
  full_options.max_view_triangles = 0;
  const auto full = reports::write_report_html(dir_, full_options);
  const std::string full_html = slurp(full.html);
  for (const std::string& note : full.notes) EXPECT_EQ(note.find("simplified"), std::string::npos) << note;

  reports::HtmlReportOptions options;
  options.max_view_triangles = 5000;
  const auto small = reports::write_report_html(dir_, options);
  const std::string html = slurp(small.html);
  EXPECT_EQ(slurp(dir_ / "heatmap.glb"), heatmap) << "heatmap.glb must stay untouched";

  std::size_t shown = 0;
  for (const char* key : {"pressure", "signal"}) {
    SCOPED_TRACE(key);
    const std::string glb = embedded_glb(html, key);
    ASSERT_FALSE(glb.empty());
    const tinygltf::Model m = parse_glb(glb);
    shown = triangle_count(m);
    EXPECT_LE(shown, 5000u);
    EXPECT_GE(shown, 4500u);
    if (std::string(key) == "signal") {
      EXPECT_EQ(shown, triangle_count(parse_glb(embedded_glb(html, "pressure"))));
    }
    const fs::path file = dir_ / (std::string("view_") + key + ".glb");
    std::ofstream(file, std::ios::binary) << glb;
    std::string log;
    EXPECT_EQ(run_validator(file, log), 0) << log;
  }
  const std::string note = "3D view simplified from " + std::to_string(n) + " to " + std::to_string(shown) +
                           " triangles (heatmap.glb keeps all " + std::to_string(n) + ")";
  EXPECT_NE(std::find(small.notes.begin(), small.notes.end(), note), small.notes.end()) << note;

  // The embedded models shrink with the triangles (the rest of the page is the same).
  const std::size_t full_models =
      embedded_glb(full_html, "pressure").size() + embedded_glb(full_html, "signal").size();
  const std::size_t small_models =
      embedded_glb(html, "pressure").size() + embedded_glb(html, "signal").size();
  std::printf("models %zu -> %zu bytes, page %zu -> %zu bytes\n", full_models, small_models, full_html.size(),
              html.size());
  EXPECT_LT(small_models * 3, full_models);
  EXPECT_LT(html.size() + full_models / 2, full_html.size());

  // Every vertex of the pressure view is an original vertex with all its
  // attributes (position, normal, uv, _SEEN, _BLANCH, COLOR_0, ...), in the original order.
  const auto before = vertex_records(original),
             after = vertex_records(parse_glb(embedded_glb(html, "pressure")));
  ASSERT_FALSE(after.empty());
  ASSERT_EQ(after[0].size(), before[0].size());
  EXPECT_LT(after.size(), before.size() / 3);
  std::size_t j = 0;
  for (std::size_t i = 0; i < after.size(); ++i) {
    while (j < before.size() && before[j] != after[i]) ++j;
    ASSERT_LT(j, before.size()) << "view vertex " << i << " is no original vertex";
    ++j;
  }
}

// A signal-only report (one view, no texture scene) is simplified the same way.
TEST_F(ReportView, SignalOnlyReportIsSimplified) {
  FixtureOptions o;
  o.n = 60;  // 14,880 triangles
  o.calibrated = false;
  make_assessment_folder(dir_, o);
  reports::HtmlReportOptions options;
  options.max_view_triangles = 3000;
  const auto result = reports::write_report_html(dir_, options);
  const std::string html = slurp(result.html);
  EXPECT_TRUE(embedded_glb(html, "pressure").empty());
  const std::string glb = embedded_glb(html, "signal");
  const std::size_t shown = triangle_count(parse_glb(glb));
  EXPECT_LE(shown, 3000u);
  EXPECT_GE(shown, 2700u);
  EXPECT_NE(std::find(result.notes.begin(), result.notes.end(),
                      "3D view simplified from 14880 to " + std::to_string(shown) +
                          " triangles (heatmap.glb keeps all 14880)"),
            result.notes.end());
  const fs::path file = dir_ / "view_signal.glb";
  std::ofstream(file, std::ios::binary) << glb;
  std::string log;
  EXPECT_EQ(run_validator(file, log), 0) << log;
}

TEST_F(ReportView, MillionTrianglesTiming) {
  if (!std::getenv("CLEARFIT_VIEW_BENCH"))
    GTEST_SKIP() << "set CLEARFIT_VIEW_BENCH=1 to time the 1M-triangle case";
  using clock = std::chrono::steady_clock;
  const Grid grid(707);  // 999,698 triangles
  auto t0 = clock::now();
  const auto s = simplify_triangles(grid.position, grid.triangles, 400000);
  std::printf("height field %zu -> %zu triangles: %.2f s\n", grid.triangles.size() / 3,
              s.triangles.size() / 3, std::chrono::duration<double>(clock::now() - t0).count());
  FixtureOptions o;
  o.n = 500;
  make_assessment_folder(dir_, o);
  const tinygltf::Model g = test::load_glb(dir_ / "heatmap.glb");  // its vertex-coloured mesh, as the page simplifies it
  const std::vector<float> position = test::heatmap_attribute(g, "POSITION", 3), colour = test::heatmap_attribute(g, "COLOR_0", 3);
  std::vector<std::uint32_t> triangles;
  for (const tinygltf::Mesh& mesh : g.meshes)
    for (const tinygltf::Primitive& p : mesh.primitives) {
      if (mesh.name != "heatmap_vertex_colors") continue;
      ASSERT_EQ(g.accessors.at(p.indices).componentType, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
      const auto t = test::read_accessor<std::uint32_t>(g, p.indices, 1);
      triangles.insert(triangles.end(), t.begin(), t.end());
    }
  t0 = clock::now();
  const auto view = simplify_triangles(position, triangles, 400000, colour);
  std::printf("slab heatmap.glb %zu -> %zu triangles: %.2f s\n", triangles.size() / 3, view.triangles.size() / 3,
              std::chrono::duration<double>(clock::now() - t0).count());
  reports::HtmlReportOptions none;
  none.max_view_triangles = 0;
  t0 = clock::now();
  const auto full = reports::write_report_html(dir_, none);
  const double t_full = std::chrono::duration<double>(clock::now() - t0).count();
  const std::size_t full_size = fs::file_size(full.html);
  t0 = clock::now();
  const auto small = reports::write_report_html(dir_);
  const double t_small = std::chrono::duration<double>(clock::now() - t0).count();
  std::printf(
      "slab n=500 report.html: %zu bytes in %.2f s unsimplified, %zu bytes in %.2f s with the default "
      "budget\n",
      full_size, t_full, static_cast<std::size_t>(fs::file_size(small.html)), t_small);
  for (const std::string& note : small.notes) std::printf("note: %s\n", note.c_str());
  EXPECT_LT(fs::file_size(small.html), full_size);
}

}  // namespace
}  // namespace clearfit
