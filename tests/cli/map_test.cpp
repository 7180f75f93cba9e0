// End-to-end tests of `clearfit map`: a slab seen by an OPENCV8 camera, the
// .npy and stats outputs checked against the closed-form slab trace
// (refraction/analytic.hpp) with the same lens model, and bad input.
#include "cli_support.hpp"

#include <clearfit/camera/camera_model.hpp>
#include <clearfit/camera/pose.hpp>
#include <clearfit/geometry/import.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <clearfit/refraction/analytic.hpp>

#include <cfloat>
#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>
#include <numbers>
#include <regex>

namespace clearfit::cli_test {
namespace {

using nlohmann::json;

// The part: slab 40 x 30 x 3 mm, contact z = 0 (group "contact"), outer z = 3.
constexpr double kSx = 40, kSy = 30, kThickness = 3;
constexpr int kW = 64, kH = 48;

CameraModel test_camera() {
  CameraModel cam;
  cam.lensmodel = "LENSMODEL_OPENCV8";
  // fx fy cx cy, k1 k2 p1 p2 k3 k4 k5 k6: a mild, asymmetric distortion.
  cam.intrinsics = {55.0, 56.5, 31.7, 23.4, -0.05, 0.01, 0.001, -0.0005, 0.0, 0.0, 0.0, 0.0};
  cam.width = kW;
  cam.height = kH;
  return cam;
}

// Camera 45 mm above the slab at (2, -1), looking down (−z), tilted 5° about x.
Rigid3 test_cam_from_part() {
  Rigid3 part_from_cam;
  const Eigen::Matrix3d down = rotation_from_rodrigues(Vec3(std::numbers::pi, 0, 0));  // diag(1, −1, −1)
  part_from_cam.rotation = rotation_from_rodrigues(Vec3(5 * std::numbers::pi / 180, 0, 0)) * down;
  part_from_cam.translation = Vec3(2, -1, 45);
  return part_from_cam.inverse();
}

struct Npy {
  std::string descr;
  bool fortran = true;
  std::vector<long> shape;
  std::vector<float> data;
};

// Minimal NumPy .npy reader (format versions 1.0 and 2.0), independent of the writer.
Npy read_npy(const fs::path& path) {
  const std::string bytes = read_text(path);
  Npy npy;
  if (bytes.size() < 10 || bytes.compare(0, 6, "\x93NUMPY") != 0) throw std::runtime_error("not an npy file");
  const int major = static_cast<unsigned char>(bytes[6]);
  std::size_t header_len = 0, start = 0;
  if (major == 1) {
    header_len = static_cast<unsigned char>(bytes[8]) | static_cast<unsigned char>(bytes[9]) << 8;
    start = 10;
  } else {
    for (int i = 0; i < 4; ++i) header_len |= std::size_t(static_cast<unsigned char>(bytes[8 + i])) << (8 * i);
    start = 12;
  }
  if ((start + header_len) % 16 != 0) throw std::runtime_error("npy data not 16-byte aligned");
  const std::string header = bytes.substr(start, header_len);
  std::smatch m;
  if (std::regex_search(header, m, std::regex(R"('descr':\s*'([^']*)')"))) npy.descr = m[1];
  if (std::regex_search(header, m, std::regex(R"('fortran_order':\s*(True|False))"))) npy.fortran = m[1] == "True";
  if (std::regex_search(header, m, std::regex(R"('shape':\s*\(([^)]*)\))"))) {
    const std::string dims = m[1];
    const std::regex number(R"(\d+)");
    for (std::sregex_iterator it(dims.begin(), dims.end(), number), end; it != end; ++it)
      npy.shape.push_back(std::stol(it->str()));
  }
  const std::size_t n = (bytes.size() - start - header_len) / sizeof(float);
  npy.data.resize(n);
  std::memcpy(npy.data.data(), bytes.data() + start + header_len, n * sizeof(float));
  return npy;
}

class Map : public CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    save_mesh(shapes::slab(kSx, kSy, kThickness, 4), work() / "slab.obj");
  }
  // The map must be the closed-form slab trace wherever that trace enters the
  // top face and reaches the contact face well inside the slab's edges.
  void check_map_against_closed_form(const fs::path& npy_path, const json& stats, const optics::Indices& n) {
    const Npy npy = read_npy(npy_path);
    EXPECT_EQ(npy.descr, "<f4");
    EXPECT_FALSE(npy.fortran);
    ASSERT_EQ(npy.shape, (std::vector<long>{kH, kW, 3}));
    ASSERT_EQ(npy.data.size(), std::size_t(kH * kW * 3));

    const CameraModel cam = test_camera();
    const Rigid3 part_from_cam = test_cam_from_part().inverse();
    const Vec3 origin = part_from_cam.translation;
    // Float32 storage of ~20 mm coordinates, plus single-precision ray casting
    // over a ~50 mm ray: a few float epsilons of 50 mm.
    const double tol = 4 * FLT_EPSILON * 50;
    const double margin = 0.05;  // mm from the slab's edges
    auto inside = [&](const Vec3& p) { return std::abs(p.x()) < kSx / 2 - margin && std::abs(p.y()) < kSy / 2 - margin; };
    long valid = 0, compared = 0;
    double worst = 0;
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        const float* p = &npy.data[(std::size_t(y) * kW + x) * 3];
        const bool is_valid = !std::isnan(p[0]);
        EXPECT_EQ(std::isnan(p[1]), !is_valid);
        EXPECT_EQ(std::isnan(p[2]), !is_valid);
        valid += is_valid;
        if (is_valid) {  // always a point of the contact face
          EXPECT_NEAR(p[2], 0.0, tol) << "pixel " << x << "," << y;
          EXPECT_LE(std::abs(p[0]), kSx / 2 + tol) << "pixel " << x << "," << y;
          EXPECT_LE(std::abs(p[1]), kSy / 2 + tol) << "pixel " << x << "," << y;
        }
        const Vec3 ray = cam.unproject(Vec2(x, y));
        ASSERT_TRUE(ray.allFinite()) << "pixel " << x << "," << y;
        const analytic::SkinHit hit = analytic::trace_slab(origin, part_from_cam.apply_direction(ray), kThickness, n);
        if (!hit.valid || !inside(hit.entry_point) || !inside(hit.skin_point)) continue;
        ++compared;
        ASSERT_TRUE(is_valid) << "pixel " << x << "," << y << " should see " << hit.skin_point.transpose();
        const double err = (Vec3(p[0], p[1], p[2]) - hit.skin_point).norm();
        worst = std::max(worst, err);
        EXPECT_LT(err, tol) << "pixel " << x << "," << y << ": map " << p[0] << " " << p[1] << " " << p[2]
                            << ", closed form " << hit.skin_point.transpose();
      }
    std::cout << "compared " << compared << " pixels with the closed form, worst " << worst * 1e6 << " nm\n";
    EXPECT_GT(compared, kW * kH / 3);   // most of the image sees the slab
    EXPECT_LT(valid, long(kW) * kH);    // and some pixels miss it
    EXPECT_GE(valid, compared);

    EXPECT_EQ(stats.at("schema"), "clearfit.map-stats/1");
    EXPECT_EQ(stats.at("image").at("width"), kW);
    EXPECT_EQ(stats.at("image").at("height"), kH);
    EXPECT_EQ(stats.at("pixels"), kW * kH);
    EXPECT_EQ(stats.at("by_status").at("valid"), valid);
    long total = 0;
    for (const auto& [reason, count] : stats.at("by_status").items()) total += count.get<long>();
    EXPECT_EQ(total, kW * kH);
    EXPECT_GT(stats.at("coverage").get<double>(), 0.0);
    EXPECT_NEAR(stats.at("coverage").get<double>(), double(valid) / (kW * kH), 1e-12);
    EXPECT_EQ(stats.at("indices").at("part"), n.n_part);
    EXPECT_EQ(stats.at("indices").at("medium"), n.n_medium);
    EXPECT_EQ(stats.at("indices").at("skin"), n.n_skin);
  }
};

TEST_F(Map, SlabWithPoseFileMatchesClosedForm) {
  write_cameramodel(test_camera(), work() / "cam.cameramodel");  // extrinsics: identity (ignored)
  write_pose_json(test_cam_from_part(), work() / "pose.json");
  const RunResult r = run({"map", "--mesh", "slab.obj", "--camera", "cam.cameramodel", "--pose", "pose.json",
                           "--contact-group", "contact", "--ior", "1.49", "--out", "m.npy", "--stats", "s.json"});
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_NE(r.out.find("wrote m.npy"), std::string::npos) << r;
  EXPECT_EQ(listing(work()), (std::set<std::string>{"slab.obj", "cam.cameramodel", "pose.json", "m.npy", "s.json"}));
  const json stats = json::parse(read_text(work() / "s.json"));
  check_map_against_closed_form(work() / "m.npy", stats, {1.0, 1.49, 1.4});
  EXPECT_EQ(stats.at("normals"), "smooth");
}

TEST_F(Map, SlabWithCameraExtrinsicsOtherIndicesFlatNormals) {
  CameraModel cam = test_camera();
  cam.cam_from_part = test_cam_from_part();
  write_cameramodel(cam, work() / "cam.cameramodel");
  // Water on the camera side, a denser resin, skin index 1.38; no --stats.
  const RunResult r = run({"map", "--mesh", "slab.obj", "--camera", "cam.cameramodel", "--contact-group", "contact",
                           "--ior", "1.55", "--medium-ior", "1.333", "--skin-ior", "1.38", "--normals", "flat",
                           "--out", "m.npy"});
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_EQ(listing(work()), (std::set<std::string>{"slab.obj", "cam.cameramodel", "m.npy"}));
  // Same run with stats, for the counts.
  const RunResult s = run({"map", "--mesh", "slab.obj", "--camera", "cam.cameramodel", "--contact-group", "contact",
                           "--ior", "1.55", "--medium-ior", "1.333", "--skin-ior", "1.38", "--normals", "flat",
                           "--out", "m2.npy", "--stats", "s.json"});
  ASSERT_EQ(s.exit_code, 0) << s;
  EXPECT_EQ(read_text(work() / "m.npy"), read_text(work() / "m2.npy"));
  const json stats = json::parse(read_text(work() / "s.json"));
  EXPECT_EQ(stats.at("normals"), "flat");
  check_map_against_closed_form(work() / "m.npy", stats, {1.333, 1.55, 1.38});
}

// Numerical limits (issue 16, section 5): indices of refraction from 1.0001 to 3 on either side, and the
// same slab given in micrometres and in metres, all follow the closed form.
TEST_F(Map, ExtremeIndicesAndMeshUnitsMatchClosedForm) {
  CameraModel cam = test_camera();
  cam.cam_from_part = test_cam_from_part();
  write_cameramodel(cam, work() / "cam.cameramodel");
  for (const auto& [name, scale] : {std::pair{"slab_um.obj", 1e3}, std::pair{"slab_m.obj", 1e-3}}) {
    Mesh m = shapes::slab(kSx, kSy, kThickness, 4);
    for (Vec3& v : m.vertices) v *= scale;
    save_mesh(m, work() / name);
  }
  struct Case {
    std::string mesh, units;
    optics::Indices n;
  };
  const Case cases[] = {{"slab.obj", "mm", {1.0, 1.0001, 1.4}}, {"slab.obj", "mm", {1.0, 3.0, 1.4}},
                        {"slab.obj", "mm", {1.0, 1.0001, 3.0}}, {"slab.obj", "mm", {1.333, 1.0001, 1.0}},
                        {"slab.obj", "mm", {1.0001, 3.0, 1.0001}}, {"slab_um.obj", "um", {1.0, 1.49, 1.4}},
                        {"slab_m.obj", "m", {1.0, 1.49, 1.4}}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.mesh + " in " + c.units + ", indices " + std::to_string(c.n.n_medium) + " / " +
                 std::to_string(c.n.n_part) + " / " + std::to_string(c.n.n_skin));
    const RunResult r = run({"map", "--mesh", c.mesh, "--units", c.units, "--camera", "cam.cameramodel",
                             "--contact-group", "contact", "--ior", std::to_string(c.n.n_part), "--medium-ior",
                             std::to_string(c.n.n_medium), "--skin-ior", std::to_string(c.n.n_skin), "--out", "m.npy",
                             "--stats", "s.json"});
    ASSERT_EQ(r.exit_code, 0) << r;
    check_map_against_closed_form(work() / "m.npy", json::parse(read_text(work() / "s.json")), c.n);
  }
}

// The bundled wristband (a tessellated 100° band, r_in 32, r_out 34.5, 24 wide,
// 96 segments) under a pinhole camera 80 mm above it: every valid point lies
// on the inner facets, and the trace follows the exact cylinder to within the
// tessellation (sag r·(1 − cos(δ/2)) = 1.3 µm, normals off by up to δ/2 = 0.52°).
TEST_F(Map, WristbandSampleFollowsTheCylinder) {
  const std::string sample = std::string(CLEARFIT_SAMPLES_DIR) + "/wristband/wristband.obj";
  CameraModel cam;
  cam.lensmodel = "LENSMODEL_PINHOLE";
  cam.intrinsics = {60, 60, 39.5, 29.5};
  cam.width = 80;
  cam.height = 60;
  Rigid3 part_from_cam;
  part_from_cam.rotation = rotation_from_rodrigues(Vec3(std::numbers::pi, 0, 0));
  part_from_cam.translation = Vec3(0, 0, 80);
  cam.cam_from_part = part_from_cam.inverse();
  write_cameramodel(cam, work() / "cam.cameramodel");
  const RunResult r = run({"map", "--mesh", sample, "--camera", "cam.cameramodel", "--contact-group", "contact",
                           "--out", "m.npy", "--stats", "s.json"});
  ASSERT_EQ(r.exit_code, 0) << r;
  const json stats = json::parse(read_text(work() / "s.json"));
  EXPECT_GT(stats.at("coverage").get<double>(), 0.2);
  const Npy npy = read_npy(work() / "m.npy");
  ASSERT_EQ(npy.shape, (std::vector<long>{60, 80, 3}));

  const double r_in = 32, r_out = 34.5, span = 100, width = 24, half = span / 2 * std::numbers::pi / 180;
  const double cos_half_step = std::cos(span / 96 / 2 * std::numbers::pi / 180);
  const double tol = 4 * FLT_EPSILON * 80;
  auto well_inside = [&](const Vec3& p) {  // 0.5 mm from the band's ends and edges
    return std::abs(p.y()) < width / 2 - 0.5 && std::abs(std::atan2(p.x(), p.z())) * r_in < half * r_in - 0.5;
  };
  long valid = 0, compared = 0;
  double worst = 0;
  for (int y = 0; y < 60; ++y)
    for (int x = 0; x < 80; ++x) {
      const float* p = &npy.data[(std::size_t(y) * 80 + x) * 3];
      if (std::isnan(p[0])) continue;
      ++valid;
      const Vec3 q(p[0], p[1], p[2]);
      const double radius = std::hypot(q.x(), q.z());
      EXPECT_GE(radius, r_in * cos_half_step - tol) << "pixel " << x << "," << y;
      EXPECT_LE(radius, r_in + tol) << "pixel " << x << "," << y;
      EXPECT_LE(std::abs(q.y()), width / 2 + tol) << "pixel " << x << "," << y;
      const analytic::SkinHit hit = analytic::trace_cylindrical_shell(
          part_from_cam.translation, part_from_cam.apply_direction(cam.unproject(Vec2(x, y))), r_in, r_out, span,
          width, {1.0, 1.49, 1.4});
      if (!hit.valid || !well_inside(hit.entry_point) || !well_inside(hit.skin_point)) continue;
      ++compared;
      worst = std::max(worst, (q - hit.skin_point).norm());
    }
  std::cout << "valid " << valid << ", compared " << compared << ", worst " << worst * 1e3 << " um from the cylinder\n";
  EXPECT_EQ(stats.at("by_status").at("valid"), valid);
  EXPECT_GT(compared, valid / 2);
  EXPECT_LT(worst, 0.01);  // 10 µm
}

// ---- bad input: exit 2, the message names the culprit, no output left behind ----

class MapBadInput : public CliTest {
 protected:
  void SetUp() override {
    CliTest::SetUp();
    save_mesh(shapes::slab(kSx, kSy, kThickness, 2), work() / "slab.obj");
    CameraModel cam = test_camera();
    cam.cam_from_part = test_cam_from_part();
    write_cameramodel(cam, work() / "cam.cameramodel");
  }
  // The arguments of a good run, with `replace` substituted / `extra` appended.
  std::vector<std::string> args(const std::vector<std::pair<std::string, std::string>>& replace = {},
                                const std::vector<std::string>& extra = {}) {
    std::vector<std::pair<std::string, std::string>> opts{{"--mesh", "slab.obj"},        {"--camera", "cam.cameramodel"},
                                                          {"--contact-group", "contact"}, {"--ior", "1.49"},
                                                          {"--out", "m.npy"},             {"--stats", "s.json"}};
    for (const auto& [key, value] : replace) {
      bool found = false;
      for (auto& o : opts)
        if (o.first == key) o.second = value, found = true;
      if (!found) opts.emplace_back(key, value);
    }
    std::vector<std::string> a{"map"};
    for (const auto& [key, value] : opts)
      if (!value.empty()) a.push_back(key), a.push_back(value);
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  }
};

TEST_F(MapBadInput, GoodRunForReference) {
  const RunResult r = run(args());
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_TRUE(fs::exists(work() / "m.npy"));
}

TEST_F(MapBadInput, MissingMesh) { expect_input_error(args({{"--mesh", "nope.obj"}}), {"nope.obj"}); }

TEST_F(MapBadInput, EmptyMeshFile) {
  write_text(work() / "empty.stl", "");
  expect_input_error(args({{"--mesh", "empty.stl"}}), {"empty.stl"});
}

TEST_F(MapBadInput, UnknownMeshExtension) {
  fs::copy_file(work() / "slab.obj", work() / "slab.step");
  expect_input_error(args({{"--mesh", "slab.step"}}), {"slab.step"});
}

TEST_F(MapBadInput, DirectoryInsteadOfFile) {
  fs::create_directory(work() / "folder.obj");
  expect_input_error(args({{"--mesh", "folder.obj"}}), {"folder.obj"});
  fs::create_directory(work() / "folder.cameramodel");
  expect_input_error(args({{"--camera", "folder.cameramodel"}}), {"folder.cameramodel"});
}

TEST_F(MapBadInput, ContactGroupThatDoesNotExist) {
  expect_input_error(args({{"--contact-group", "skin"}}), {"slab.obj", "'skin'"});
}

TEST_F(MapBadInput, NoContactSurfaceGiven) {
  expect_input_error(args({{"--contact-group", ""}}), {"contact"});
}

TEST_F(MapBadInput, NormalConeSelectingNothing) {
  // Slab faces point along ±x, ±y, ±z: a 10° cone about (1,1,0) holds none of them.
  expect_input_error(args({{"--contact-group", ""}, {"--contact-normal", "1,1,0"}, {"--contact-angle", "10"}}),
                     {"slab.obj", "selects no faces"});
}

// One run per bad value (each test stays well under 2 s): {option, value}.
class MapBadIndex : public MapBadInput,
                    public ::testing::WithParamInterface<std::pair<const char*, const char*>> {};

TEST_P(MapBadIndex, IsRefusedAndNamed) {
  const auto [option, value] = GetParam();
  expect_input_error(args({{option, value}}), {option});
}

INSTANTIATE_TEST_SUITE_P(Values, MapBadIndex,
                         ::testing::Values(std::pair{"--ior", "NaN"}, std::pair{"--ior", "inf"},
                                           std::pair{"--ior", "0"}, std::pair{"--ior", "-1"},
                                           std::pair{"--ior", "0.5"}, std::pair{"--ior", "abc"},
                                           std::pair{"--skin-ior", "0"}, std::pair{"--medium-ior", "-1.333"}));

TEST_F(MapBadInput, BogusUnits) { expect_input_error(args({{"--units", "bogus"}}), {"--units", "bogus"}); }

TEST_F(MapBadInput, PoseBehindTheCamera) {
  Rigid3 behind = test_cam_from_part();
  behind.translation.z() = -behind.translation.z();  // the part 45 mm behind the lens
  write_pose_json(behind, work() / "behind.json");
  expect_input_error(args({{"--pose", "behind.json"}}), {"behind.json", "behind the camera"});
}

TEST_F(MapBadInput, GarbagePoseFile) {
  write_text(work() / "pose.json", "{\"schema\": \"clearfit.pose/1\", \"cam_from_part\": {\"r\": [0, 0,");
  expect_input_error(args({{"--pose", "pose.json"}}), {"pose.json"});
  expect_input_error(args({{"--pose", "no_pose.json"}}), {"no_pose.json"});
}

TEST_F(MapBadInput, GarbageCameraModel) {
  write_text(work() / "garbage.cameramodel", "this is not a camera model\n\x01\x02\x03");
  expect_input_error(args({{"--camera", "garbage.cameramodel"}}), {"garbage.cameramodel"});
}

TEST_F(MapBadInput, EmptyOrMissingCameraModel) {
  write_text(work() / "empty.cameramodel", "");
  expect_input_error(args({{"--camera", "empty.cameramodel"}}), {"empty.cameramodel"});
  expect_input_error(args({{"--camera", "no_such.cameramodel"}}), {"no_such.cameramodel"});
}

TEST_F(MapBadInput, TruncatedCameraModel) {
  const std::string good = read_text(work() / "cam.cameramodel");
  write_text(work() / "cut.cameramodel", good.substr(0, good.size() / 2));
  expect_input_error(args({{"--camera", "cut.cameramodel"}}), {"cut.cameramodel"});
}

TEST_F(MapBadInput, WrongIntrinsicsCount) {
  write_text(work() / "short.cameramodel",
             "{\n 'lensmodel': 'LENSMODEL_OPENCV8',\n 'intrinsics': [55, 55, 31.5, 23.5, 0, 0],\n"
             " 'imagersize': [64, 48],\n 'extrinsics': [0, 0, 0, 0, 0, 45],\n}\n");
  expect_input_error(args({{"--camera", "short.cameramodel"}}), {"short.cameramodel", "intrinsics"});
}

TEST_F(MapBadInput, PrincipalPointFarOutsideTheImager) {
  // 64 x 48 imager whose optical centre sits 5000 px to the right: no lens is
  // built like that; a mixed-up imagersize or intrinsics (e.g. a model made for
  // another resolution) must be refused, not mapped.
  // write_cameramodel refuses such a model, so write the text by hand.
  CameraModel cam = test_camera();
  std::ofstream f(work() / "offcentre.cameramodel");
  f << "{ 'lensmodel': '" << cam.lensmodel << "', 'intrinsics': [";
  for (std::size_t i = 0; i < cam.intrinsics.size(); ++i) f << (i == 2 ? 5000.0 : cam.intrinsics[i]) << ", ";
  f << "], 'imagersize': [" << cam.width << ", " << cam.height << "], }\n";
  f.close();
  expect_input_error(args({{"--camera", "offcentre.cameramodel"}}), {"offcentre.cameramodel"});
}

TEST_F(MapBadInput, OutInAFolderThatDoesNotExist) {
  expect_input_error(args({{"--out", "no_dir/m.npy"}}), {"no_dir/m.npy"});
}

TEST_F(MapBadInput, StatsInAFolderThatDoesNotExist) {
  // The map itself is fine, but the run fails: neither output may be left behind.
  expect_input_error(args({{"--stats", "no_dir/s.json"}}), {"no_dir/s.json"});
}

TEST_F(MapBadInput, MissingRequiredOptions) {
  expect_input_error({"map", "--camera", "cam.cameramodel", "--contact-group", "contact", "--out", "m.npy"},
                     {"--mesh"});
  expect_input_error({"map", "--mesh", "slab.obj", "--camera", "cam.cameramodel", "--contact-group", "contact"},
                     {"--out"});
}

}  // namespace
}  // namespace clearfit::cli_test
