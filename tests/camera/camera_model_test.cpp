// CameraModel: .cameramodel read/write (against mrcal's Python as the
// independent reader/writer), validation errors, projection against
// mrcal.project, round trips, and the per-pixel ray grid against
// mrcal_unproject at every pixel.
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/pixel_unprojector.hpp>
#include <clearfit/camera/projection_uncertainty.hpp>
#include <clearfit/error.hpp>

#include "../support/outside_tools.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <random>
#include <ctime>
#include <memory>
#include <unistd.h>

namespace clearfit {
namespace {

namespace fs = std::filesystem;

constexpr unsigned kSeed = 4242;

CameraModel opencv8(int width = 640, int height = 480) {
  CameraModel m;
  m.lensmodel = "LENSMODEL_OPENCV8";
  const double s = width / 640.0;  // same field of view at every resolution
  m.intrinsics = {520.3 * s, 519.8 * s, (width - 1) / 2.0 + 2.2 * s, (height - 1) / 2.0 - 1.1 * s,
                  -0.28, 0.11, 8.3e-4, -5.1e-4, -0.021, 4.7e-4, 2.3e-4, 1.05e-3};
  m.width = width;
  m.height = height;
  m.cam_from_part = Rigid3::from_rt({0.02, -0.31, 0.05, 4.5, -12.25, 180.0});
  return m;
}

CameraModel pinhole() {
  CameraModel m;
  m.lensmodel = "LENSMODEL_PINHOLE";
  m.intrinsics = {400.5, 401.25, 159.3, 121.7};
  m.width = 320;
  m.height = 240;
  return m;
}

// Stereographic core plus a gently perturbed spline surface (fixed seed).
CameraModel splined() {
  CameraModel m;
  m.lensmodel = "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=10_Ny=8_fov_x_deg=120";
  m.intrinsics = {300.0, 301.5, 160.2, 119.4};
  std::mt19937 rng(kSeed);
  std::uniform_real_distribution<double> u(-3e-3, 3e-3);
  for (int k = 0; k < 2 * 10 * 8; ++k) m.intrinsics.push_back(u(rng));
  m.width = 320;
  m.height = 240;
  m.cam_from_part = Rigid3::from_rt({-0.4, 0.1, 0.2, 0, 0, 90});
  return m;
}

double angle_between(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

class CameraFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("clearfit_camera_" + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" + info->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path text_file(const std::string& name, const std::string& text) const {
    std::ofstream(dir_ / name) << text;
    return dir_ / name;
  }
  // Runs a Python script with /usr/bin/python3 and returns the JSON it prints.
  nlohmann::json python(const std::string& script, const std::vector<std::string>& args) const {
    const auto py = text_file("script.py", script);
    const auto out = dir_ / "python_out.json";
    std::string cmd = "/usr/bin/python3 " + py.string();
    for (const auto& a : args) cmd += " '" + a + "'";
    cmd += " > " + out.string();
    if (std::system(cmd.c_str()) != 0) throw std::runtime_error("python failed: " + cmd);
    return nlohmann::json::parse(std::ifstream(out));
  }
  fs::path dir_;
};

std::vector<Vec3> sample_points(const CameraModel& m, int n) {
  // Points seen by the camera: unproject random pixels (slightly beyond the
  // imager too) and scale to random depths in mm.
  std::mt19937 rng(kSeed);
  std::uniform_real_distribution<double> ux(-5, m.width + 4), uy(-5, m.height + 4), depth(5, 2000);
  std::vector<Vec2> px(n);
  for (auto& q : px) q = {ux(rng), uy(rng)};
  auto rays = m.unproject(px);
  for (auto& r : rays) r *= depth(rng);
  return rays;
}

// ---------------------------------------------------------------- files

TEST_F(CameraFiles, WriteReadRoundTripIsExact) {
  for (const CameraModel& m : {opencv8(), pinhole(), splined()}) {
    const auto path = dir_ / "m.cameramodel";
    write_cameramodel(m, path);
    const CameraModel back = read_cameramodel(path);
    EXPECT_EQ(back.lensmodel, m.lensmodel);
    EXPECT_EQ(back.intrinsics, m.intrinsics) << m.lensmodel;  // bit for bit
    EXPECT_EQ(back.width, m.width);
    EXPECT_EQ(back.height, m.height);
    EXPECT_EQ(back.path, path);
    EXPECT_LT((back.cam_from_part.rotation - m.cam_from_part.rotation).cwiseAbs().maxCoeff(), 1e-15);
    EXPECT_LT((back.cam_from_part.translation - m.cam_from_part.translation).norm(), 1e-13);
    EXPECT_EQ(back.intrinsics_hash(), m.intrinsics_hash());
  }
}

// The projection uncertainty's keys (projection_uncertainty.hpp): written with the model, read back exactly,
// skipped by mrcal's C reader (read_cameramodel) and by mrcal's Python reader; a model without them has none;
// some of the keys without the others, both grids, or a wrong count, is refused naming the key.
TEST_F(CameraFiles, ProjectionUncertaintyTravelsWithTheModel) {
  const CameraModel m = opencv8();
  const ProjectionUncertainty u{3, 2, 412.5, {0.11, 0.2, 0.35, 0.1, 0.05, 1.0 / 3}};
  EXPECT_EQ(u.layout, ProjectionUncertainty::Layout::nodes);
  const auto path = dir_ / "u.cameramodel";
  write_cameramodel(m, u, path);
  const CameraModel back = read_cameramodel(path);
  EXPECT_EQ(back.intrinsics, m.intrinsics);
  const auto read = read_projection_uncertainty(path);
  ASSERT_TRUE(read);
  EXPECT_EQ(read->layout, ProjectionUncertainty::Layout::nodes);
  EXPECT_EQ(read->nx, 3);
  EXPECT_EQ(read->ny, 2);
  EXPECT_EQ(read->distance_mm, 412.5);
  EXPECT_EQ(read->px, u.px);  // bit for bit
  // The nodes span the imager edge to edge (node i of n at i·(W − 1)/(n − 1)): at them the values, the image's
  // corner pixels included; halfway between two nodes their mean; outside the imager the nearest edge's.
  const double W = m.width, H = m.height;
  auto node = [&](double ix, double iy) { return Vec2(ix * (W - 1) / 2, iy * (H - 1)); };
  const auto pixels = uncertainty_sample_pixels(ProjectionUncertainty::Layout::nodes, 3, 2, m.width, m.height);
  ASSERT_EQ(pixels.size(), 6u);
  EXPECT_EQ(pixels[0], Vec2(0, 0));
  EXPECT_EQ(pixels[5], Vec2(W - 1, H - 1));
  for (int iy = 0; iy < 2; ++iy)
    for (int ix = 0; ix < 3; ++ix) {
      EXPECT_NEAR((pixels[iy * 3 + ix] - node(ix, iy)).norm(), 0, 1e-12);
      EXPECT_NEAR(read->at(node(ix, iy), m.width, m.height), u.px[iy * 3 + ix], 1e-12);
    }
  EXPECT_NEAR(read->at(node(0.5, 0), m.width, m.height), (0.11 + 0.2) / 2, 1e-12);
  EXPECT_NEAR(read->at(node(2, 0.5), m.width, m.height), (0.35 + 1.0 / 3) / 2, 1e-12);
  EXPECT_NEAR(read->at(node(1.5, 0.25), m.width, m.height), 0.75 * (0.2 + 0.35) / 2 + 0.25 * (0.05 + 1.0 / 3) / 2, 1e-12);
  EXPECT_NEAR(read->at(Vec2(-0.5, -0.5), m.width, m.height), 0.11, 1e-12);
  EXPECT_NEAR(read->at(Vec2(W - 0.5, H - 0.5), m.width, m.height), 1.0 / 3, 1e-12);
  EXPECT_DOUBLE_EQ(read->largest(), 1.0 / 3 > 0.35 ? 1.0 / 3 : 0.35);
  write_cameramodel(m, dir_ / "plain.cameramodel");
  EXPECT_FALSE(read_projection_uncertainty(dir_ / "plain.cameramodel"));
  if (test::python_ready("mrcal", "python3-mrcal")) {
    const auto j = python("import sys, json, mrcal\nm = mrcal.cameramodel(sys.argv[1])\nprint(json.dumps(list(m.intrinsics()[1])))\n",
                          {path.string()});
    EXPECT_EQ(j.get<std::vector<double>>(), m.intrinsics);
  }
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("'clearfit_uncertainty_nodes': [ 3, 2, ]"), std::string::npos) << text;
  EXPECT_EQ(text.find("clearfit_uncertainty_cells"), std::string::npos) << text;
  auto refused = [&](const std::string& from, const std::string& to, const std::string& key) {
    std::string bad = text;
    bad.replace(bad.find(from), from.size(), to);
    const auto p = text_file("bad.cameramodel", bad);
    try {
      read_projection_uncertainty(p);
      ADD_FAILURE() << "accepted " << to;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  };
  refused("'clearfit_uncertainty_distance_mm'", "'other_key'", "clearfit_uncertainty_distance_mm");
  refused("'clearfit_uncertainty_nodes'", "'other_key'", "clearfit_uncertainty_nodes");
  refused("[ 3, 2, ]", "[ 4, 2, ]", "clearfit_uncertainty_px");
  refused("[ 3, 2, ]", "[ 6, 1, ]", "clearfit_uncertainty_nodes");  // one node cannot span the image's height
  refused("'clearfit_uncertainty_px': [ 0.11", "'clearfit_uncertainty_px': [ -0.11", "clearfit_uncertainty_px");
  refused("'clearfit_uncertainty_distance_mm'", "'clearfit_uncertainty_cells': [ 3, 2, ],\n    'clearfit_uncertainty_distance_mm'",
          "one grid");
  // The writer refuses a grid of nodes that cannot span the imager.
  EXPECT_THROW(write_cameramodel(m, ProjectionUncertainty{1, 1, 100, {0.1}}, dir_ / "one.cameramodel"), std::invalid_argument);
}

// Models written before the nodes carry 'clearfit_uncertainty_cells': values at the centres of cells
// ((c + 0.5)·W/n − 0.5). They are read as before: the values at the centres, bilinear between them, the
// nearest beyond the outer centres (the image's edges and corners take the outer centres' values); and
// written back in the same layout (clearfit simulate --scale rewrites the model it was given).
TEST_F(CameraFiles, OlderModelsWithCellsReadAsBefore) {
  const CameraModel m = opencv8();
  const auto path = text_file("cells.cameramodel", "");
  write_cameramodel(m, path);
  std::string text;
  {
    std::ifstream in(path);
    text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  text.insert(text.rfind('}'), "    'clearfit_uncertainty_cells': [ 3, 2, ],\n    'clearfit_uncertainty_distance_mm': 412.5,\n"
                               "    'clearfit_uncertainty_px': [ 0.11, 0.2, 0.35, 0.1, 0.05, 0.3333333333333333, ],\n");
  text_file("cells.cameramodel", text);
  const auto read = read_projection_uncertainty(path);
  ASSERT_TRUE(read);
  EXPECT_EQ(read->layout, ProjectionUncertainty::Layout::cells);
  EXPECT_EQ(read->nx, 3);
  EXPECT_EQ(read->ny, 2);
  const std::vector<double> px{0.11, 0.2, 0.35, 0.1, 0.05, 1.0 / 3};
  EXPECT_EQ(read->px, px);
  const double W = m.width, H = m.height;
  auto centre = [&](double cx, double cy) { return Vec2((cx + 0.5) * W / 3 - 0.5, (cy + 0.5) * H / 2 - 0.5); };
  const auto pixels = uncertainty_sample_pixels(ProjectionUncertainty::Layout::cells, 3, 2, m.width, m.height);
  for (int cy = 0; cy < 2; ++cy)
    for (int cx = 0; cx < 3; ++cx) {
      EXPECT_NEAR((pixels[cy * 3 + cx] - centre(cx, cy)).norm(), 0, 1e-12);
      EXPECT_NEAR(read->at(centre(cx, cy), m.width, m.height), px[cy * 3 + cx], 1e-12);
    }
  EXPECT_NEAR(read->at(centre(0.5, 0), m.width, m.height), (0.11 + 0.2) / 2, 1e-12);
  EXPECT_NEAR(read->at(centre(2, 0.5), m.width, m.height), (0.35 + 1.0 / 3) / 2, 1e-12);
  EXPECT_NEAR(read->at(Vec2(-0.5, -0.5), m.width, m.height), 0.11, 1e-12);
  EXPECT_NEAR(read->at(Vec2(0, 0), m.width, m.height), 0.11, 1e-12);
  EXPECT_NEAR(read->at(Vec2(W - 1, H - 1), m.width, m.height), 1.0 / 3, 1e-12);
  const auto again = dir_ / "again.cameramodel";
  write_cameramodel(m, *read, again);
  const auto back = read_projection_uncertainty(again);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->layout, ProjectionUncertainty::Layout::cells);
  EXPECT_EQ(back->px, px);
  // A cell may be alone on its axis (its value then holds across it).
  const ProjectionUncertainty one{1, 1, 100, {0.25}, ProjectionUncertainty::Layout::cells};
  write_cameramodel(m, one, dir_ / "one.cameramodel");
  EXPECT_NEAR(read_projection_uncertainty(dir_ / "one.cameramodel")->at(Vec2(W - 1, 0), m.width, m.height), 0.25, 1e-12);
}

TEST_F(CameraFiles, OurReaderReadsMrcalPythonFileWithIdenticalValues) {
  CLEARFIT_REQUIRE_PYTHON("mrcal", "python3-mrcal");
  const CameraModel m = opencv8();
  const auto path = dir_ / "python.cameramodel";
  const auto rt = m.cam_from_part.to_rt();
  python(
      "import sys, json, numpy as np, mrcal\n"
      "a = json.loads(sys.argv[2])\n"
      "m = mrcal.cameramodel(intrinsics=(a['lensmodel'], np.array(a['intrinsics'])),"
      " imagersize=a['imagersize'], extrinsics_rt_fromref=np.array(a['rt']))\n"
      "m.write(sys.argv[1])\n"
      "print('{}')\n",
      {path.string(), nlohmann::json{{"lensmodel", m.lensmodel},
                                     {"intrinsics", m.intrinsics},
                                     {"imagersize", {m.width, m.height}},
                                     {"rt", rt}}
                          .dump()});
  const CameraModel back = read_cameramodel(path);
  EXPECT_EQ(back.lensmodel, m.lensmodel);
  EXPECT_EQ(back.intrinsics, m.intrinsics);
  EXPECT_EQ(back.width, m.width);
  EXPECT_EQ(back.height, m.height);
  const auto back_rt = back.cam_from_part.to_rt();
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(back_rt[k], rt[k], 1e-13) << k;
}

void expect_model_error(const fs::path& path, const std::string& element_part, const std::string& message_part) {
  try {
    read_cameramodel(path);
    ADD_FAILURE() << "no error for " << path;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), path.string());
    EXPECT_NE(e.element().find(element_part), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(message_part), std::string::npos) << e.what();
  }
}

std::string model_text(const std::string& lens, const std::string& intrinsics, const std::string& size = "640, 480") {
  return "{\n    'lensmodel':  '" + lens + "',\n    'intrinsics': [ " + intrinsics +
         " ],\n    'extrinsics': [ 0, 0, 0, 0, 0, 0 ],\n    'imagersize': [ " + size + " ],\n}\n";
}

TEST_F(CameraFiles, BadFilesThrowInputErrorNamingTheFile) {
  // mrcal's parser prints its own complaint to stderr for the malformed ones.
  expect_model_error(dir_ / "missing.cameramodel", "", "does not exist");
  expect_model_error(dir_, "", "not a file");
  expect_model_error(text_file("empty.cameramodel", ""), "", "empty");
  expect_model_error(text_file("garbage.cameramodel", "\x01\x02 this is not a camera model ]]"), "",
                     "not an mrcal .cameramodel");
  expect_model_error(text_file("lens.cameramodel", model_text("LENSMODEL_FOO", "500, 500, 320, 240")),
                     "line 2, key 'lensmodel'", "unknown lens model 'LENSMODEL_FOO'");
  expect_model_error(text_file("config.cameramodel", model_text("LENSMODEL_SPLINED_STEREOGRAPHIC", "500, 500, 320, 240")),
                     "key 'lensmodel'", "configuration");
  expect_model_error(text_file("count.cameramodel", model_text("LENSMODEL_OPENCV8", "500, 500, 320, 240, 0.1, 0.01")),
                     "line 3, key 'intrinsics'", "has 6 values; LENSMODEL_OPENCV8 needs 12");
  expect_model_error(
      text_file("cahvore.cameramodel",
                model_text("LENSMODEL_CAHVORE_linearity=0.34", "500,500,320,240,0,0,0,0,0,0,0,0")),
      "key 'lensmodel'", "not supported");
  expect_model_error(text_file("size.cameramodel", model_text("LENSMODEL_PINHOLE", "500, 500, 320, 240", "0, 480")),
                     "key 'imagersize'", "positive");
  expect_model_error(text_file("focal.cameramodel", model_text("LENSMODEL_PINHOLE", "-500, 500, 320, 240")),
                     "key 'intrinsics'", "focal lengths");
}

// A text mrcal's parser refuses (a value of another key that is not a number): mrcal's complaint, which it
// prints on stderr as "cameramodel-parser.re(N): ... at BYTE", is in the error instead, with the line.
TEST_F(CameraFiles, MrcalsParseComplaintIsInTheErrorNotOnStderr) {
  std::string text = model_text("LENSMODEL_PINHOLE", "500, 500, 320, 240");
  text.insert(text.rfind('}'), "    'clearfit_uncertainty_px': [ 0.1x ],\n");
  const auto path = text_file("unparsed.cameramodel", text);
  testing::internal::CaptureStderr();
  std::string what;
  try {
    read_cameramodel(path);
  } catch (const InputError& e) {
    what = e.what();
  }
  const std::string printed = testing::internal::GetCapturedStderr();
  EXPECT_EQ(printed, "");
  EXPECT_NE(what.find(path.string() + ": mrcal cannot parse this .cameramodel file: "), std::string::npos) << what;
  EXPECT_NE(what.find("Error parsing value for key 'clearfit_uncertainty_px' on line 6"), std::string::npos) << what;
}

TEST(CameraModel, ValidateInMemoryModels) {
  EXPECT_NO_THROW(opencv8().validate());
  EXPECT_NO_THROW(splined().validate());
  CameraModel m = pinhole();
  m.path = "cam.cameramodel";
  m.intrinsics.push_back(0.1);
  EXPECT_THROW(m.validate(), InputError);
  m = pinhole();
  m.intrinsics[2] = std::numeric_limits<double>::infinity();
  EXPECT_THROW(m.validate(), InputError);
  m = pinhole();
  m.height = -1;
  EXPECT_THROW(m.validate(), InputError);
  // Both writers refuse it naming the file, the key and the defect, and write nothing.
  const ProjectionUncertainty u{2, 2, 100, {0.1, 0.1, 0.1, 0.1}};
  for (const bool with_uncertainty : {false, true}) {
    SCOPED_TRACE(with_uncertainty ? "with the projection uncertainty" : "the model alone");
    try {
      with_uncertainty ? write_cameramodel(m, u, "never_written.cameramodel") : write_cameramodel(m, "never_written.cameramodel");
      ADD_FAILURE() << "written";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), "write_cameramodel(never_written.cameramodel): key 'imagersize' must be two positive integers, found " +
                                           std::to_string(m.width) + " x -1");
    }
    EXPECT_FALSE(fs::exists("never_written.cameramodel"));
  }
}

TEST(CameraModel, IntrinsicsHashSeesIntrinsicsAndSizeNotPose) {
  const CameraModel a = opencv8();
  CameraModel b = a;
  b.cam_from_part = Rigid3::identity();
  b.path = "elsewhere";
  EXPECT_EQ(a.intrinsics_hash(), b.intrinsics_hash());
  b.intrinsics[5] = std::nextafter(b.intrinsics[5], 1.0);  // one ulp
  EXPECT_NE(a.intrinsics_hash(), b.intrinsics_hash());
  b = a;
  b.width = 641;
  EXPECT_NE(a.intrinsics_hash(), b.intrinsics_hash());
  b = a;
  b.lensmodel = "LENSMODEL_OPENCV12";
  EXPECT_NE(a.intrinsics_hash(), b.intrinsics_hash());
}

// ---------------------------------------------------------------- projection

// One Python run for all three models (importing mrcal takes ~1.5 s): mrcal's
// Python reads our files with identical values, and its project/unproject
// agree with ours.
TEST_F(CameraFiles, MatchesMrcalPython) {
  CLEARFIT_REQUIRE_PYTHON("mrcal", "python3-mrcal");
  std::printf("seed %u\n", kSeed);
  const std::vector<CameraModel> models = {opencv8(), pinhole(), splined()};
  std::vector<std::vector<Vec3>> points;
  std::vector<std::vector<Vec2>> pixels;
  nlohmann::json jobs = nlohmann::json::array();
  for (std::size_t k = 0; k < models.size(); ++k) {
    const CameraModel& m = models[k];
    const auto path = dir_ / ("m" + std::to_string(k) + ".cameramodel");
    write_cameramodel(m, path);
    points.push_back(sample_points(m, 500));
    points.back().push_back({0, 0, 1});
    points.back().push_back({-3, 2, 1e-3});  // steep
    pixels.emplace_back();
    for (double y = 0; y < m.height; y += 37.5)
      for (double x = 0; x < m.width; x += 41.25) pixels.back().emplace_back(x, y);
    nlohmann::json job{{"model", path.string()}, {"points", nlohmann::json::array()}, {"pixels", nlohmann::json::array()}};
    for (const auto& p : points.back()) job["points"].push_back({p.x(), p.y(), p.z()});
    for (const auto& q : pixels.back()) job["pixels"].push_back({q.x(), q.y()});
    jobs.push_back(job);
  }
  std::ofstream(dir_ / "jobs.json") << jobs.dump();
  const auto ref = python(
      "import sys, json, numpy as np, mrcal\n"
      "out = []\n"
      "for job in json.load(open(sys.argv[1])):\n"
      "    m = mrcal.cameramodel(job['model'])\n"
      "    lens, intr = m.intrinsics()\n"
      "    out.append({'lensmodel': lens, 'intrinsics': intr.tolist(),\n"
      "                'imagersize': m.imagersize().tolist(), 'rt': m.extrinsics_rt_fromref().tolist(),\n"
      "                'q': mrcal.project(np.array(job['points']), lens, intr).tolist(),\n"
      "                'v': mrcal.unproject(np.array(job['pixels']), lens, intr, normalize=True).tolist()})\n"
      "print(json.dumps(out))\n",
      {(dir_ / "jobs.json").string()});
  ASSERT_EQ(ref.size(), models.size());
  for (std::size_t k = 0; k < models.size(); ++k) {
    const CameraModel& m = models[k];
    const auto& r = ref[k];
    SCOPED_TRACE(m.lensmodel);
    EXPECT_EQ(r["lensmodel"], m.lensmodel);
    EXPECT_EQ(r["intrinsics"].get<std::vector<double>>(), m.intrinsics);  // bit for bit
    EXPECT_EQ(r["imagersize"][0], m.width);
    EXPECT_EQ(r["imagersize"][1], m.height);
    const auto rt = m.cam_from_part.to_rt();
    for (int i = 0; i < 6; ++i) EXPECT_EQ(r["rt"][i].get<double>(), rt[i]) << i;

    const auto q = m.project(points[k]);
    ASSERT_EQ(r["q"].size(), q.size());
    double worst = 0;
    for (std::size_t i = 0; i < q.size(); ++i)
      worst = std::max(worst, (q[i] - Vec2(r["q"][i][0].get<double>(), r["q"][i][1].get<double>())).norm());
    EXPECT_LT(worst, 1e-9) << "project";

    const auto v = m.unproject(pixels[k]);
    ASSERT_EQ(r["v"].size(), v.size());
    worst = 0;
    for (std::size_t i = 0; i < v.size(); ++i) {
      const auto& x = r["v"][i];
      worst = std::max(worst, angle_between(v[i], Vec3(x[0].get<double>(), x[1].get<double>(), x[2].get<double>())));
    }
    EXPECT_LT(worst, 1e-9) << "unproject";
  }
}

CameraModel simple(const std::string& lensmodel) {
  CameraModel m = pinhole();
  m.lensmodel = lensmodel;
  m.intrinsics = {210.5, 205.25, 161.1, 118.9};  // pixels per unit tangent / per radian
  return m;
}

TEST(CameraModel, UnprojectProjectRoundTrip) {
  for (const CameraModel& m : {opencv8(), pinhole(), splined(), simple("LENSMODEL_STEREOGRAPHIC"),
                               simple("LENSMODEL_LONLAT"), simple("LENSMODEL_LATLON")}) {
    std::vector<Vec2> px;
    for (double y = -0.5; y <= m.height - 0.5; y += 7.3)
      for (double x = -0.5; x <= m.width - 0.5; x += 6.1) px.emplace_back(x, y);
    const auto rays = m.unproject(px);
    double worst = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
      ASSERT_TRUE(rays[i].allFinite()) << m.lensmodel << " pixel " << px[i].transpose();
      EXPECT_NEAR(rays[i].norm(), 1.0, 1e-15);
    }
    std::vector<Vec3> points(rays.size());
    for (std::size_t i = 0; i < rays.size(); ++i) points[i] = rays[i] * (10.0 + i % 500);  // depth is irrelevant
    const auto back = m.project(points);
    for (std::size_t i = 0; i < px.size(); ++i) worst = std::max(worst, (back[i] - px[i]).norm());
    EXPECT_LT(worst, 1e-6) << m.lensmodel;
  }
}

TEST(CameraModel, PinholeMatchesClosedForm) {
  const CameraModel m = pinhole();
  const Vec3 p(12.5, -7.25, 300);
  const Vec2 q = m.project(p);
  EXPECT_NEAR(q.x(), 400.5 * 12.5 / 300 + 159.3, 1e-12);
  EXPECT_NEAR(q.y(), 401.25 * -7.25 / 300 + 121.7, 1e-12);
  const Vec3 r = m.unproject(Vec2(10, 200));
  EXPECT_LT(angle_between(r, Vec3((10 - 159.3) / 400.5, (200 - 121.7) / 401.25, 1)), 1e-15);
}

TEST(CameraModel, FailuresAreNaN) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const CameraModel cv = opencv8();
  const std::vector<Vec3> bad = {{0, 0, 0}, {1, 1, -1}, {1, 1, 0}, {nan, 0, 1}, {0, 0, INFINITY}};
  for (const auto& q : cv.project(bad)) EXPECT_TRUE(q.array().isNaN().all()) << q.transpose();
  EXPECT_TRUE(cv.project(Vec3(1, 1, 5)).allFinite());
  // Stereographic-based models see behind the image plane.
  const CameraModel sp = splined();
  EXPECT_TRUE(sp.project(Vec3(1, 0, -0.2)).allFinite());
  EXPECT_TRUE(sp.unproject(Vec2(nan, 3)).array().isNaN().all());
  std::vector<Vec3> three(3, Vec3(0, 0, 1));
  std::vector<Vec2> two(2);
  EXPECT_THROW(cv.project(three, two), std::invalid_argument);
}

TEST(CameraModel, ParallelBatchEqualsSingleThread) {
  const CameraModel m = opencv8();
  std::vector<Vec2> px;
  for (int k = 0; k < 5000; ++k) px.emplace_back((k * 37) % 640, (k * 53) % 480);
  const auto parallel = m.unproject(px);
  std::vector<Vec3> serial;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    serial = m.unproject(px);
  }
  for (std::size_t i = 0; i < px.size(); ++i) ASSERT_EQ(parallel[i], serial[i]) << i;
}

// ---------------------------------------------------------------- ray grid

double max_angle(const RayGrid& a, const RayGrid& b) {
  double worst = 0;
  for (std::size_t i = 0; i < a.rays.size(); ++i) worst = std::max(worst, angle_between(a.rays[i], b.rays[i]));
  return worst;
}

TEST(RayGrid, NewtonRouteMatchesMrcalUnprojectAtEveryPixel) {
  for (const CameraModel& m : {opencv8(320, 240), splined()}) {
    UnprojectImageOptions exact_opt, newton_opt;
    exact_opt.method = UnprojectMethod::exact;
    newton_opt.method = UnprojectMethod::coarse_grid_newton;
    const RayGrid exact = unproject_image(m, 1, exact_opt);
    const RayGrid fast = unproject_image(m, 1, newton_opt);
    ASSERT_EQ(fast.rays.size(), std::size_t(m.width) * m.height);
    EXPECT_EQ(fast.exact_fallbacks, 0) << m.lensmodel;
    EXPECT_LT(max_angle(fast, exact), 1e-9) << m.lensmodel;
    EXPECT_EQ(fast.intrinsics_hash, m.intrinsics_hash());
    // The refined rays reproject onto their pixels.
    std::vector<Vec2> px(fast.rays.size());
    for (int j = 0; j < fast.height; ++j)
      for (int i = 0; i < fast.width; ++i) px[j * fast.width + i] = fast.pixel(i, j);
    const auto back = m.project(fast.rays);
    double worst = 0;
    for (std::size_t i = 0; i < px.size(); ++i) worst = std::max(worst, (back[i] - px[i]).norm());
    EXPECT_LT(worst, 1e-8) << m.lensmodel;
  }
}

TEST(PixelUnprojector, ScatteredPixelsMatchMrcalUnproject) {
  // Fractional pixels anywhere on the imager (edges and corners included), in
  // no order, against mrcal_unproject one by one; a closed-form lens goes the
  // exact route.
  const unsigned seed = 1729;
  std::printf("  seed %u\n", seed);
  std::mt19937 rng(seed);
  for (const CameraModel& m : {opencv8(320, 240), splined(), pinhole()}) {
    std::uniform_real_distribution<double> ux(0, m.width - 1), uy(0, m.height - 1);
    std::vector<Vec2> px = {{0, 0}, {m.width - 1.0, m.height - 1.0}, {0, m.height - 1.0}, {m.width - 1.0, 0}};
    for (int i = 0; i < 5000; ++i) px.emplace_back(ux(rng), uy(rng));
    std::vector<Vec3> fast(px.size());
    const int fallbacks = PixelUnprojector(m).unproject(px, fast);
    EXPECT_EQ(fallbacks, 0) << m.lensmodel;
    double worst = 0;
    for (std::size_t i = 0; i < px.size(); ++i) worst = std::max(worst, angle_between(fast[i], m.unproject(px[i])));
    EXPECT_LT(worst, 1e-9) << m.lensmodel;
  }
}

TEST(RayGrid, StrideAndCoarseStepVariants) {
  const CameraModel m = opencv8(200, 150);
  UnprojectImageOptions opt;
  opt.coarse_step_px = 7;  // does not divide the size: uneven last cell
  const RayGrid g = unproject_image(m, 3, opt);
  EXPECT_EQ(g.width, 67);
  EXPECT_EQ(g.height, 50);
  EXPECT_EQ(g.stride, 3);
  double worst = 0;
  for (int j = 0; j < g.height; j += 7)
    for (int i = 0; i < g.width; i += 5) worst = std::max(worst, angle_between(g.at(i, j), m.unproject(g.pixel(i, j))));
  EXPECT_LT(worst, 1e-9);
  opt.coarse_step_px = 1000;  // one cell: poor start, Newton must still converge or fall back
  const RayGrid coarse = unproject_image(m, 1, opt);
  UnprojectImageOptions exact_opt;
  exact_opt.method = UnprojectMethod::exact;
  EXPECT_LT(max_angle(coarse, unproject_image(m, 1, exact_opt)), 1e-9);
}

TEST(RayGrid, PinholeUsesClosedForm) {
  const CameraModel m = pinhole();
  const RayGrid g = unproject_image(m);
  const auto& k = m.intrinsics;
  double worst = 0;
  for (int j = 0; j < g.height; ++j)
    for (int i = 0; i < g.width; ++i)
      worst = std::max(worst, angle_between(g.at(i, j), Vec3((i - k[2]) / k[0], (j - k[3]) / k[1], 1)));
  EXPECT_LT(worst, 1e-15);
}

TEST(RayGrid, OptionsAreValidated) {
  EXPECT_NO_THROW(UnprojectImageOptions{}.validate());
  UnprojectImageOptions o;
  o.coarse_step_px = 0;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  o = {};
  o.tolerance_px = 0;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  EXPECT_THROW(unproject_image(pinhole(), 0), std::invalid_argument);
}

// Timing study (not a test): run with --gtest_also_run_disabled_tests
// --gtest_filter='*Timing*'. Prints mrcal_unproject at every pixel against
// the coarse grid + Newton route (wall time, and CPU time of the calling
// thread for the one-thread runs), and their largest angle apart.
TEST(RayGrid, DISABLED_TimingOpencv8) {
  using clock = std::chrono::steady_clock;
  const auto cpu = [] {
    timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
  };
  for (auto [w, h] : {std::pair{640, 480}, std::pair{1920, 1080}}) {
    const CameraModel m = opencv8(w, h);
    UnprojectImageOptions exact_opt, newton_opt;
    exact_opt.method = UnprojectMethod::exact;
    newton_opt.method = UnprojectMethod::coarse_grid_newton;
    for (int threads : {1, 0}) {
      std::unique_ptr<tbb::global_control> limit;
      if (threads) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
      const auto t0 = clock::now();
      const double c0 = cpu();
      const RayGrid exact = unproject_image(m, 1, exact_opt);
      const auto t1 = clock::now();
      const double c1 = cpu();
      const RayGrid fast = unproject_image(m, 1, newton_opt);
      const auto t2 = clock::now();
      const double c2 = cpu();
      const double we = std::chrono::duration<double>(t1 - t0).count(), wn = std::chrono::duration<double>(t2 - t1).count();
      std::printf("OPENCV8 %dx%d threads=%s: mrcal_unproject %.1f ms, grid+Newton %.1f ms (%.1fx)", w, h,
                  threads ? "1" : "all", 1e3 * we, 1e3 * wn, we / wn);
      if (threads == 1)
        std::printf(" [CPU %.1f vs %.1f ms, %.1fx]", 1e3 * (c1 - c0), 1e3 * (c2 - c1), (c1 - c0) / (c2 - c1));
      std::printf(", max angle %.2e rad, fallbacks %d\n", max_angle(fast, exact), fast.exact_fallbacks);
    }
  }
}

}  // namespace
}  // namespace clearfit
