// Part pose from tags: known poses recovered, uncertainty against repeated
// noisy trials, refused tags, layout files.
#include <clearfit/camera/detect.hpp>
#include <clearfit/camera/render_board.hpp>
#include <clearfit/camera/tag_pose.hpp>
#include <clearfit/error.hpp>
#include <clearfit/geometry/ray_index.hpp>
#include <clearfit/geometry/shapes.hpp>

#include <gtest/gtest.h>

#include <unistd.h>
#include <Eigen/Geometry>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

namespace clearfit {
namespace {

namespace fs = std::filesystem;
const fs::path kData = CLEARFIT_TEST_DATA_DIR "/boards";

CameraModel lens() { return read_cameramodel(kData / "opencv8_640x480.cameramodel"); }

TagLayout::Tag square_tag(int id, const Eigen::Vector3d& origin, const Eigen::Vector3d& right,
                          const Eigen::Vector3d& down, double size) {
  TagLayout::Tag t;
  t.id = id;
  t.corners_mm = {origin + size * down, origin + size * (right + down), origin + size * right, origin};
  return t;
}

/// Six 15 mm tags on an L-shaped fixture around the part origin (two planes).
TagLayout fixture_layout() {
  TagLayout l;
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY(),
                        z = Eigen::Vector3d::UnitZ();
  for (int i = 0; i < 4; ++i) l.tags.push_back(square_tag(i, {-50.0 + 30 * i, -40, 0}, x, y, 15));
  l.tags.push_back(square_tag(4, {-50, 30, 0}, x, -z, 15));
  l.tags.push_back(square_tag(5, {20, 30, 0}, x, -z, 15));
  return l;
}

Rigid3 truth_pose() {
  Rigid3 p;
  p.rotation =
      (Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(-0.5, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  p.translation = {5, -8, 230};
  return p;
}

std::vector<DetectedTag> project_tags(const CameraModel& cam, const TagLayout& l, const Rigid3& cam_from_part,
                                      std::mt19937_64* rng, double sigma) {
  std::normal_distribution<double> noise(0.0, sigma);
  std::vector<DetectedTag> out;
  for (const auto& t : l.tags) {
    DetectedTag d;
    d.id = t.id;
    for (int k = 0; k < 4; ++k) {
      d.corners[k] = cam.project(Vec3(cam_from_part.apply(t.corners_mm[k])));
      if (rng) d.corners[k] += Eigen::Vector2d(noise(*rng), noise(*rng));
      d.weight[k] = 1.0;
    }
    out.push_back(d);
  }
  return out;
}

Eigen::Vector3d rotation_error(const Rigid3& est, const Rigid3& truth) {
  return rodrigues_from_rotation(est.rotation * truth.rotation.transpose());
}

TEST(TagPose, ExactCornersGiveTheExactPose) {
  const CameraModel cam = lens();
  const TagLayout l = fixture_layout();
  const PartPose p = solve_part_pose(cam, l, {project_tags(cam, l, truth_pose(), nullptr, 0)});
  EXPECT_LT((p.cam_from_part.translation - truth_pose().translation).norm(), 1e-6);
  EXPECT_LT(rotation_error(p.cam_from_part, truth_pose()).norm(), 1e-8);
  EXPECT_LT(p.rms_px, 1e-6);
  EXPECT_EQ(p.tags, 6);
  EXPECT_EQ(p.corners, 24);
}

TEST(TagPose, UncertaintyMatchesRepeatedNoisyTrials) {
  const CameraModel cam = lens();
  const TagLayout l = fixture_layout();
  const std::uint64_t seed = 4242;
  std::printf("seed %llu\n", static_cast<unsigned long long>(seed));
  std::mt19937_64 rng(seed);
  const double sigma = 0.3;
  const int trials = 300;
  Eigen::Matrix<double, 6, 1> sum2 = Eigen::Matrix<double, 6, 1>::Zero(), predicted = sum2;
  double noise_sum = 0;
  for (int i = 0; i < trials; ++i) {
    const PartPose p = solve_part_pose(cam, l, {project_tags(cam, l, truth_pose(), &rng, sigma)});
    Eigen::Matrix<double, 6, 1> e;
    e << rotation_error(p.cam_from_part, truth_pose()) * 180 / M_PI,
        p.cam_from_part.translation - truth_pose().translation;
    sum2 += e.cwiseProduct(e);
    predicted.head<3>() += p.sigma_rotation_deg.cwiseProduct(p.sigma_rotation_deg);
    predicted.tail<3>() += p.sigma_translation_mm.cwiseProduct(p.sigma_translation_mm);
    noise_sum += p.noise_px;
  }
  const Eigen::Matrix<double, 6, 1> empirical = (sum2 / trials).cwiseSqrt(),
                                    model = (predicted / trials).cwiseSqrt();
  std::printf("noise estimate %.4f px (true %.2f)\n", noise_sum / trials, sigma);
  const char* names[6] = {"rot x deg", "rot y deg", "rot z deg", "t x mm", "t y mm", "t z mm"};
  for (int k = 0; k < 6; ++k) {
    std::printf("%-10s empirical %.5f predicted %.5f ratio %.3f\n", names[k], empirical[k], model[k],
                empirical[k] / model[k]);
    EXPECT_GT(empirical[k] / model[k], 0.8) << names[k];
    EXPECT_LT(empirical[k] / model[k], 1.25) << names[k];
  }
  EXPECT_NEAR(noise_sum / trials, sigma, 0.03);
}

TEST(TagPose, RenderedFixtureThroughTheLens) {
  // A printed board serves as the fixture: its tags' corners in the part frame
  // are the board corners moved by part_from_board.
  const CameraModel cam = lens();
  const Board board = make_board({"tag36h11", 3, 4, 20.0, 20.0, 10});
  Rigid3 part_from_board;
  part_from_board.rotation = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  part_from_board.translation = {-60, -40, 5};
  TagLayout layout;
  for (int id = 10; id < 22; ++id) {
    TagLayout::Tag t;
    t.id = id;
    for (int k = 0; k < 4; ++k)
      t.corners_mm[k] = part_from_board.apply(board.point_mm(*board.corner_grid_index(id, k)));
    layout.tags.push_back(t);
  }
  const Rigid3 cam_from_part = truth_pose();
  const Rigid3 cam_from_board = cam_from_part * part_from_board;
  RenderOptions ro;
  ro.noise_sigma = 1.5;
  ro.blur_sigma_px = 0.5;
  ro.seed = 7;
  const cv::Mat img = render_board(board, cam, cam_from_board, ro);
  std::vector<std::string> notes;
  const auto tags = detect_tags(img, "tag36h11", {}, &cam, &notes);
  ASSERT_EQ(tags.size(), 12u);
  const PartPose p = solve_part_pose(cam, layout, {tags});
  const double dt = (p.cam_from_part.translation - cam_from_part.translation).norm();
  const double dr = rotation_error(p.cam_from_part, cam_from_part).norm() * 180 / M_PI;
  std::printf(
      "rendered: rms %.4f px, noise %.4f px, error %.4f mm %.5f deg, sigma t %.4f %.4f %.4f mm, r %.5f %.5f "
      "%.5f deg\n",
      p.rms_px, p.noise_px, dt, dr, p.sigma_translation_mm.x(), p.sigma_translation_mm.y(),
      p.sigma_translation_mm.z(), p.sigma_rotation_deg.x(), p.sigma_rotation_deg.y(),
      p.sigma_rotation_deg.z());
  EXPECT_LT(p.rms_px, 0.1);
  EXPECT_LT(dt, 5 * p.sigma_translation_mm.norm() + 0.02);
  EXPECT_LT(dt, 0.3);
  EXPECT_LT(dr, 0.1);
}

TEST(TagPose, RefusedUnknownAndTooFewTags) {
  const CameraModel cam = lens();
  TagLayout l = fixture_layout();
  l.tags[0].through_part = true;
  auto seen = project_tags(cam, l, truth_pose(), nullptr, 0);
  DetectedTag stranger = seen[1];
  stranger.id = 99;
  seen.push_back(stranger);
  const PartPose p = solve_part_pose(cam, l, {seen});
  EXPECT_EQ(p.tags, 5);
  std::string notes;
  for (const auto& n : p.notes) notes += n + "\n";
  EXPECT_NE(notes.find("tag 0 refused: flagged through_part"), std::string::npos) << notes;
  EXPECT_NE(notes.find("not in the layout ignored: 99"), std::string::npos) << notes;
  EXPECT_THROW(solve_part_pose(cam, l, {{seen[0]}}), InputError);  // only the refused tag
  EXPECT_THROW(solve_part_pose(cam, l, {}), InputError);
}

TEST(TagPose, TagsSeenThroughThePartAreFound) {
  const CameraModel cam = lens();
  const TagLayout l = fixture_layout();
  const PartPose p = solve_part_pose(cam, l, {project_tags(cam, l, truth_pose(), nullptr, 0)});
  // A 30 x 30 mm plate 20 mm above tag 1 (centre (-12.5, -32.5, 0)), between it and the camera.
  Mesh plate = shapes::slab(30, 30, 3);
  const Eigen::Vector3d centre(-12.5, -32.5, 0), cam_centre = p.cam_from_part.inverse().translation;
  const Eigen::Vector3d at = centre + 0.1 * (cam_centre - centre);
  for (auto& v : plate.vertices) v += at;
  const auto index = make_ray_index(plate);
  EXPECT_EQ(tags_seen_through_part(*index, p, l), std::vector<int>{1});
}

class LayoutFile : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("clearfit_layout_" + std::to_string(::getpid()));
  void SetUp() override { fs::create_directories(dir); }
  void TearDown() override { fs::remove_all(dir); }
  fs::path write(const std::string& text) {
    std::ofstream(dir / "l.yaml") << text;
    return dir / "l.yaml";
  }
  std::string error_of(const std::string& text) {
    try {
      read_tag_layout(write(text));
    } catch (const InputError& e) {
      return e.what();
    }
    return "accepted";
  }
};

TEST_F(LayoutFile, ReadsTagsAndRefusesBadOnes) {
  const std::string head = "schema: clearfit.tag-layout/1\nfamily: tag36h11\ntags:\n";
  const TagLayout l = read_tag_layout(write(
      head +
      "  - id: 3\n    corners_mm: [[0, 10, 0], [10, 10, 0], [10, 0, 0], [0, 0, 0]]\n"
      "  - {id: 4, corners_mm: [[20, 10, 0], [30, 10, 0], [30, 0, 0], [20, 0, 0]], through_part: true}\n"));
  ASSERT_EQ(l.tags.size(), 2u);
  EXPECT_EQ(l.tags[0].id, 3);
  EXPECT_EQ(l.tags[0].corners_mm[1], Eigen::Vector3d(10, 10, 0));
  EXPECT_TRUE(l.tags[1].through_part);
  // Corners out of order (a bow tie), not a square.
  EXPECT_NE(error_of(head + "  - id: 3\n    corners_mm: [[0, 10, 0], [10, 0, 0], [10, 10, 0], [0, 0, 0]]\n")
                .find("line 4"),
            std::string::npos);
  EXPECT_NE(
      error_of(head + "  - id: 3\n    corners_mm: [[0, 10, 0], [10, 10, 0], [10, 0, 0]]\n").find("4 corners"),
      std::string::npos);
  EXPECT_NE(error_of(head + "  - {id: 3, corners_mm: [[0, 10, 0], [10, 10, 0], [10, 0, 0], [0, 0, 0]]}\n"
                            "  - {id: 3, corners_mm: [[0, 10, 0], [10, 10, 0], [10, 0, 0], [0, 0, 0]]}\n")
                .find("twice"),
            std::string::npos);
  EXPECT_NE(error_of("schema: clearfit.tag-layout/1\nfamily: tag99\ntags: []\n").find("family"),
            std::string::npos);
  EXPECT_NE(error_of(head + "  - {id: 3, corner: 1}\n").find("unknown key"), std::string::npos);
  EXPECT_NE(error_of(head + "  - {[id]: 3}\n").find("line 4: a key is a list, a map or empty"), std::string::npos);
  EXPECT_NE(error_of("{a: 1}: 2\n").find("line 1: a key is a list, a map or empty"), std::string::npos);
}

}  // namespace
}  // namespace clearfit
