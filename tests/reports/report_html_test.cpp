// report.html from a hand-made assessment folder: the hotspot table matches
// report.json, text is escaped, odd reports (no hotspots, no calibration,
// missing files) still give a page, bad folders are named.
#include <clearfit/error.hpp>
#include <clearfit/reports/report_html.hpp>
#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <cstring>
#include <regex>
#include <sstream>

#include "../support/glb_read.hpp"
#include "report_fixture.hpp"

namespace clearfit {
namespace {

using report_test::FixtureOptions;
using report_test::make_assessment_folder;
namespace fs = std::filesystem;
using json = nlohmann::json;

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::size_t count(const std::string& hay, const std::string& needle) {
  std::size_t n = 0;
  for (std::size_t pos = hay.find(needle); pos != std::string::npos; pos = hay.find(needle, pos + 1)) ++n;
  return n;
}

// Whether the page's text (between <main> and </main>, images left out) shows a NaN or an infinity.
bool shows_nan(const std::string& html) {
  const std::size_t a = html.find("<main>"), b = html.find("</main>");
  const std::string text = std::regex_replace(html.substr(a, b - a), std::regex("data:[^\"]*"), "");
  return std::regex_search(text, std::regex("(^|[^a-z])(nan|inf)([^a-z]|$)", std::regex::icase));
}

class ReportHtml : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / (std::string("clearfit_report_html_") + info->name() + "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  std::string generate(const FixtureOptions& o, json* report = nullptr, reports::HtmlReportResult* result = nullptr) {
    const json r = make_assessment_folder(dir_, o);
    if (report) *report = r;
    const auto res = reports::write_report_html(dir_);
    if (result) *result = res;
    EXPECT_EQ(res.html, dir_ / "report.html");
    return slurp(res.html);
  }
  fs::path dir_;
};

std::string fixed2(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", v);
  return buf;
}

TEST(HtmlEscape, EscapesEveryMarkupCharacter) {
  EXPECT_EQ(reports::html_escape("a<b>&\"c'"), "a&lt;b&gt;&amp;&quot;c&#39;");
  EXPECT_EQ(reports::html_escape("plain text, 12 kPa"), "plain text, 12 kPa");
}

TEST_F(ReportHtml, HotspotTableMatchesReportJson) {
  json report;
  const std::string html = generate({}, &report);
  ASSERT_EQ(report["hotspots"].size(), 2u);
  const std::regex row_re(R"re(<tr data-hotspot="(\d+)">(.*?)</tr>)re");
  const std::regex cell_re(R"re(<td data-key="([a-z_0-9]+)" data-value="([^"]*)">([^<]*)</td>)re");
  int rows = 0;
  for (auto it = std::sregex_iterator(html.begin(), html.end(), row_re); it != std::sregex_iterator(); ++it, ++rows) {
    const int id = std::stoi((*it)[1]);
    const json& h = report["hotspots"][id - 1];
    ASSERT_EQ(h["id"], id);
    const std::string cells = (*it)[2];
    std::map<std::string, std::pair<std::string, std::string>> by_key;
    for (auto c = std::sregex_iterator(cells.begin(), cells.end(), cell_re); c != std::sregex_iterator(); ++c)
      by_key[(*c)[1]] = {(*c)[2], (*c)[3]};
    for (const char* key : {"peak_kpa", "peak_sigma_kpa", "mean_kpa", "mean_sigma_kpa", "centroid_sigma_mm", "centre_of_pressure_sigma_mm"}) {
      ASSERT_TRUE(by_key.count(key)) << key;
      EXPECT_DOUBLE_EQ(std::stod(by_key[key].first), h[key].get<double>()) << key;
      EXPECT_EQ(by_key[key].second, fixed2(h[key].get<double>())) << key;
    }
    // One row per place, its area (± σ) at each threshold in a column of its own.
    for (std::size_t l = 0; l < h["levels"].size(); ++l) {
      const json& level = h["levels"][l];
      char area[64];
      std::snprintf(area, sizeof area, "%.1f &plusmn; %.1f", level["area_mm2"].get<double>(), level["area_sigma_mm2"].get<double>());
      const std::string key = "area_mm2_" + std::to_string(l);
      ASSERT_TRUE(by_key.count(key)) << key;
      EXPECT_EQ(by_key[key].second, area) << key;
      EXPECT_DOUBLE_EQ(std::stod(by_key[key].first), level["area_mm2"].get<double>()) << key;
    }
    EXPECT_EQ(json::parse(by_key["centroid_mm"].first), h["centroid_mm"]);
  }
  EXPECT_EQ(rows, 2);
  // One clickable marker and one info box per hotspot; two views (pressure, signal) with a toggle.
  EXPECT_EQ(count(html, "slot=\"hotspot-"), 2u);
  EXPECT_EQ(count(html, "class=\"hotspot-info\" data-hotspot-info="), 2u);
  EXPECT_EQ(count(html, "class=\"clearfit-model\""), 2u);
  EXPECT_NE(html.find("<button type=\"button\" data-view=\"signal\">"), std::string::npos);
  EXPECT_NE(html.find("the study's linear fit reached 0.439"), std::string::npos);
  EXPECT_NE(html.find("2 hotspots (thresholds 4.3 and 5.5 kPa); the strongest is #1: 20.0 &plusmn; 1.3 kPa"), std::string::npos);
  EXPECT_NE(html.find("motion during the worn capture: 0.8 px, compensated"), std::string::npos);
  EXPECT_FALSE(shows_nan(html)) << "a NaN was printed";
  // Self-contained: no external URL is referenced.
  EXPECT_EQ(html.find("src=\"http"), std::string::npos);
  EXPECT_EQ(html.find("href=\"http"), std::string::npos);
  // No temporary file is left beside it.
  for (const auto& e : fs::directory_iterator(dir_)) EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
}

// The hover's vertex table (report.js shows a vertex's kPa ± σ and signal from it): exactly the heatmap's
// seen vertices, each with its position and its _PRESSURE_KPA, _PRESSURE_SIGMA_KPA and _BLANCH as the .glb
// holds them (read back here with the .glb reader); without a calibration the kPa columns are NaN. Below
// detection (the fixture's pressure under 2 kPa: 0 kPa and no σ, which the .glb stores as 0) the σ is NaN.
TEST_F(ReportHtml, HoverTableHoldsEverySeenVertexWithItsValues) {
  for (const double detection_kpa : {0.0, 2.0, -1.0}) {
    FixtureOptions o;
    o.calibrated = detection_kpa >= 0;
    o.detection_kpa = std::max(0.0, detection_kpa);
    const bool calibrated = o.calibrated;
    const std::string html = generate(o);
    const std::string open = "id=\"clearfit-data\">";
    const std::size_t a = html.find(open) + open.size(), b = html.find("</script>", a);
    const json vertices = json::parse(html.substr(a, b - a)).at("vertices");
    const tinygltf::Model glb = test::load_glb(dir_ / "heatmap.glb");
    const std::vector<float> position_mm = test::heatmap_attribute(glb, "POSITION", 3), seen_flag = test::heatmap_attribute(glb, "_SEEN");
    const std::vector<float> kpa = test::heatmap_attribute(glb, "_PRESSURE_KPA"), sigma = test::heatmap_attribute(glb, "_PRESSURE_SIGMA_KPA"),
                             signal = test::heatmap_attribute(glb, "_BLANCH");
    ASSERT_EQ(seen_flag.size() * 3, position_mm.size());
    const std::string rows_bytes = test::base64_decode(vertices.at("rows").get<std::string>());
    const std::string ids_bytes = test::base64_decode(vertices.at("ids").get<std::string>());
    const std::size_t n = vertices.at("count").get<std::size_t>();
    ASSERT_EQ(rows_bytes.size(), n * 6 * sizeof(float));
    ASSERT_EQ(ids_bytes.size(), n * sizeof(std::uint32_t));
    std::vector<float> rows(6 * n);
    std::vector<std::uint32_t> ids(n);
    std::memcpy(rows.data(), rows_bytes.data(), rows_bytes.size());
    std::memcpy(ids.data(), ids_bytes.data(), ids_bytes.size());
    std::size_t seen = 0;
    for (float f : seen_flag) seen += f > 0.5f;
    EXPECT_EQ(n, seen);
    EXPECT_EQ(vertices.at("calibrated").get<bool>(), calibrated);
    EXPECT_GT(vertices.at("reach_mm").get<double>(), 0);
    auto same = [](float x, float y) { return x == y || (std::isnan(x) && std::isnan(y)); };
    std::size_t below = 0, no_sigma = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t v = ids[i];
      ASSERT_LT(v, seen_flag.size());
      ASSERT_GT(seen_flag[v], 0.5f) << "vertex " << v;
      for (int c = 0; c < 3; ++c) ASSERT_EQ(rows[6 * i + c], position_mm[3 * v + c]) << "vertex " << v;
      ASSERT_TRUE(same(rows[6 * i + 3], calibrated ? kpa[v] : NAN)) << "vertex " << v;
      ASSERT_TRUE(same(rows[6 * i + 4], calibrated && sigma[v] > 0 ? sigma[v] : NAN)) << "vertex " << v;
      ASSERT_TRUE(same(rows[6 * i + 5], signal[v])) << "vertex " << v;
      if (calibrated && kpa[v] > 0) EXPECT_GT(rows[6 * i + 4], 0.f) << "vertex " << v;
      // Below detection is the analytic field under the detection limit: 0 kPa and no σ.
      const double truth = report_test::fixture_pressure(o, position_mm[3 * v], position_mm[3 * v + 1]);
      if (calibrated && o.detection_kpa > 0 && truth < o.detection_kpa) {
        ++below;
        EXPECT_EQ(rows[6 * i + 3], 0.f) << "vertex " << v;
      }
      no_sigma += calibrated && std::isnan(rows[6 * i + 4]);
    }
    EXPECT_EQ(no_sigma, below) << "detection " << o.detection_kpa;
    if (o.detection_kpa > 0) EXPECT_GT(below, n / 4);
  }
}

// The 3D view's numbered markers stand beside their places, not on them: on the seen surface, where the
// fixture's analytic pressure is below the lowest threshold (4.3 kPa) and beyond the radius at which a
// Gaussian bump falls to it, σ·√(2 ln(peak/4.3)), but near it (within the 5 % of the part's diagonal the
// label needs and a mesh cell more); data-centroid is the place's centroid.
TEST_F(ReportHtml, MarkersStandBesideTheirPlaces) {
  for (const bool calibrated : {true, false}) {
    FixtureOptions o;
    o.calibrated = calibrated;
    const std::string html = generate(o);
    const std::regex marker_re(R"re(data-hotspot="(\d+)" data-position="([^"]+)" data-centroid="([^"]+)")re");
    const double cell_mm = std::hypot(40.0 / o.n, 30.0 / o.n), margin_mm = 0.05 * std::sqrt(40.0 * 40 + 30 * 30 + 3 * 3);
    int markers = 0;
    for (auto it = std::sregex_iterator(html.begin(), html.end(), marker_re); it != std::sregex_iterator(); ++it, ++markers) {
      const report_test::Bump& b = o.bumps.at(std::stoi((*it)[1]) - 1);
      double p[3], c[3];
      std::istringstream((*it)[2]) >> p[0] >> p[1] >> p[2];
      std::istringstream((*it)[3]) >> c[0] >> c[1] >> c[2];
      for (double* v : {p, c})
        for (int k = 0; k < 3; ++k) v[k] /= 0.001;  // the scene's metres to mm
      EXPECT_LE(std::hypot(c[0] - b.x_mm, c[1] - b.y_mm), 1e-6) << "place " << (*it)[1];
      const double r_outline = b.sigma_mm * std::sqrt(2 * std::log(b.peak_kpa / 4.3));
      const double r = std::hypot(p[0] - b.x_mm, p[1] - b.y_mm);
      EXPECT_LT(report_test::fixture_pressure(o, p[0], p[1]), 4.3) << "place " << (*it)[1] << " marker at " << p[0] << ", " << p[1];
      EXPECT_GT(r, r_outline) << "place " << (*it)[1];
      EXPECT_LT(r, r_outline + margin_mm + cell_mm) << "place " << (*it)[1];
      EXPECT_NEAR(p[2], 0, 1e-9) << "the marker lies on the contact face";
      EXPECT_LE(p[0], 17 + 1e-9) << "the marker lies on the seen part of the plate";
    }
    EXPECT_EQ(markers, 2);
  }
}

TEST_F(ReportHtml, EscapesMaliciousText) {
  const std::string plain = generate({});
  FixtureOptions o;
  o.odd_text = "<script>alert(\"x\")</script><img src=x onerror=alert(1)>&'";
  const std::string html = generate(o);
  EXPECT_EQ(html.find("<img src=x"), std::string::npos);
  EXPECT_EQ(html.find("<script>alert"), std::string::npos);
  EXPECT_NE(html.find("&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;&lt;img src=x onerror=alert(1)&gt;&amp;&#39;"),
            std::string::npos);
  // The only <script> elements are the page's own, as for a plain report.
  EXPECT_EQ(count(html, "<script"), count(plain, "<script"));
  EXPECT_EQ(count(html, "</script"), count(plain, "</script"));
}

TEST_F(ReportHtml, NoHotspots) {
  FixtureOptions o;
  o.bumps = {{0, 0, 3, 3}};  // below the 5.5 kPa threshold
  json report;
  const std::string html = generate(o, &report);
  ASSERT_TRUE(report["hotspots"].empty());
  EXPECT_NE(html.find("id=\"no-hotspots\""), std::string::npos);
  EXPECT_EQ(html.find("id=\"hotspot-table\""), std::string::npos);
  EXPECT_EQ(count(html, "slot=\"hotspot-"), 0u);
  EXPECT_NE(html.find("No hotspot above"), std::string::npos);
}

TEST_F(ReportHtml, SaysWhatShareOfTheHotspotsIsUnseen) {
  json report = make_assessment_folder(dir_, FixtureOptions{});
  std::string html = slurp(reports::write_report_html(dir_).html);
  EXPECT_EQ(html.find("unseen beside the hotspots"), std::string::npos) << "nothing unseen: no row";
  // A wall seen edge-on beside the first place: 4.1 of its 4.1 + 12.3 mm² unseen.
  report["hotspots"][0]["unseen_area_mm2"] = 4.1;
  report["hotspots"][0]["unseen_share"] = 4.1 / 16.4;
  report["coverage"]["pressed_seen_mm2"] = 12.3;
  report["coverage"]["pressed_unseen_mm2"] = 4.1;
  report["coverage"]["pressed_unseen_share"] = 0.25;
  std::ofstream(dir_ / "report.json") << report.dump(2);
  html = slurp(reports::write_report_html(dir_).html);
  EXPECT_NE(html.find("<th scope=\"row\">unseen beside the hotspots</th><td>4.1 mm&sup2; = 25.0 %"), std::string::npos);
  EXPECT_NE(html.find("<li>25.0 % of the hotspots' area is not seen"), std::string::npos);
  EXPECT_FALSE(shows_nan(html));
}

TEST_F(ReportHtml, SignalOnlyWithoutCalibration) {
  FixtureOptions o;
  o.calibrated = false;
  json report;
  const std::string html = generate(o, &report);
  EXPECT_NE(html.find("id=\"no-calibration\""), std::string::npos);
  EXPECT_NE(html.find("Regions of significant blanching"), std::string::npos);
  EXPECT_NE(html.find("data-key=\"peak_signal\""), std::string::npos);
  EXPECT_EQ(html.find("data-key=\"peak_kpa\""), std::string::npos);
  // One view, the signal, and no toggle.
  EXPECT_EQ(count(html, "class=\"clearfit-model\""), 1u);
  EXPECT_NE(html.find("class=\"clearfit-model\" data-view=\"signal\""), std::string::npos);
  EXPECT_EQ(html.find("class=\"toggle\""), std::string::npos);
  EXPECT_FALSE(shows_nan(html));
}

// The signal view is heatmap.glb recoloured from _BLANCH: read it back from
// the page and check its colours against the colormap directly.
// In each 3D view the heatmap (the contact primitive) stays unlit, as the chart images are coloured, while the
// rest of the part is drawn lit in its vertex colours (the no-data grey: base colour factor 1), so that its
// shape and outline read apart from the unseen contact surface's flat grey.
TEST_F(ReportHtml, ViewsDrawTheHeatmapUnlitAndThePartLit) {
  const std::string html = generate({});
  for (const char* key : {"pressure", "signal"}) {
    const std::string glb = test::embedded_glb(html, key);
    ASSERT_FALSE(glb.empty()) << key;
    const tinygltf::Model model = test::parse_glb(glb);
    const tinygltf::Mesh& mesh = model.meshes.at(model.nodes.at(model.scenes[model.defaultScene].nodes[0]).mesh);
    int contact = 0, rest = 0;
    for (const tinygltf::Primitive& p : mesh.primitives) {
      const std::string name = model.accessors.at(p.indices).name;
      const tinygltf::Material& m = model.materials.at(p.material);
      const bool unlit = m.extensions.count("KHR_materials_unlit") > 0;
      if (name == "contact") {
        ++contact;
        EXPECT_TRUE(unlit) << key;
      } else if (name == "rest") {
        ++rest;
        EXPECT_FALSE(unlit) << key;
        for (int c = 0; c < 4; ++c) EXPECT_EQ(m.pbrMetallicRoughness.baseColorFactor[c], 1.0) << key;
      }
    }
    EXPECT_EQ(contact, 1) << key;
    EXPECT_EQ(rest, 1) << key;
  }
}

// A capture read from a folder of images has no frame rate (fps 0 in report.json): the captures table shows a
// dash, where it showed "0.0"; a video's rate is shown.
TEST_F(ReportHtml, ImageFolderCapturesShowNoFrameRate) {
  json report = make_assessment_folder(dir_, FixtureOptions{});
  report["captures"]["baseline"]["fps"] = 0.0;
  std::ofstream(dir_ / "report.json") << report.dump(2);
  const std::string html = slurp(reports::write_report_html(dir_).html);
  EXPECT_NE(html.find("<td>plain.mp4</td><td>10&ndash;99 of 120</td><td>\xE2\x80\x94 (images)</td>"), std::string::npos);
  EXPECT_NE(html.find("<td>worn.mp4</td><td>20&ndash;119 of 120</td><td>60.0</td>"), std::string::npos);
  EXPECT_FALSE(shows_nan(html));
}

TEST_F(ReportHtml, SignalViewIsRecolouredFromBlanch) {
  const std::string html = generate({});
  const std::string glb = test::embedded_glb(html, "signal");
  ASSERT_FALSE(glb.empty());
  const tinygltf::Model model = test::parse_glb(glb);
  ASSERT_EQ(model.scenes.size(), 1u);  // one scene per view: model-viewer loads them all
  EXPECT_EQ(model.scenes.at(model.defaultScene).name, "vertex_colors");
  const tinygltf::Mesh& mesh = model.meshes.at(model.nodes.at(model.scenes[model.defaultScene].nodes[0]).mesh);
  auto floats = [&](int accessor) {
    return test::read_accessor<float>(model, accessor, tinygltf::GetNumComponentsInType(model.accessors[accessor].type));
  };
  const auto colour = floats(mesh.primitives[0].attributes.at("COLOR_0"));
  const auto blanch = floats(mesh.primitives[0].attributes.at("_BLANCH"));
  const auto seen = floats(mesh.primitives[0].attributes.at("_SEEN"));
  const Colormap& cm = Colormap::get("viridis");
  const std::size_t top = std::max_element(blanch.begin(), blanch.end()) - blanch.begin();
  const Eigen::Vector3f top_colour = cm.linear(1.0), grey = cm.no_data_linear(), low = cm.linear(0.0);
  for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(colour[3 * top + c], top_colour[c]);
  int unseen = 0, zero = 0;
  for (std::size_t v = 0; v < seen.size(); ++v) {
    if (seen[v] < 0.5f) {
      ++unseen;
      for (int c = 0; c < 3; ++c) ASSERT_FLOAT_EQ(colour[3 * v + c], grey[c]) << v;
    } else if (blanch[v] == 0.0f) {
      ++zero;
      for (int c = 0; c < 3; ++c) ASSERT_FLOAT_EQ(colour[3 * v + c], low[c]) << v;
    }
  }
  EXPECT_GT(unseen, 0);
}

TEST_F(ReportHtml, MissingImagesLeaveANote) {
  FixtureOptions o;
  o.write_pngs = false;
  reports::HtmlReportResult result;
  const std::string html = generate(o, nullptr, &result);
  EXPECT_NE(html.find("skin_camera.png is missing"), std::string::npos);
  EXPECT_EQ(html.find("data:image/png"), std::string::npos);
  EXPECT_GE(result.notes.size(), 4u);
}

TEST_F(ReportHtml, BadFoldersAreNamed) {
  fs::create_directories(dir_);
  try {
    reports::write_report_html(dir_);
    FAIL() << "no error for a folder without report.json";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("report.json"), std::string::npos) << e.what();
  }
  std::ofstream(dir_ / "report.json") << R"({"schema": "clearfit.report/0"})";
  try {
    reports::write_report_html(dir_);
    FAIL() << "no error for another schema";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("schema"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir_ / "report.html"));
  make_assessment_folder(dir_);
  reports::HtmlReportOptions opt;
  opt.assets_dir = dir_ / "no-assets-here";
  try {
    reports::write_report_html(dir_, opt);
    FAIL() << "no error without assets";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("vendor-viewer.sh"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace clearfit
