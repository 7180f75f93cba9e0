// Rigid3 against closed forms and Eigen's AngleAxis; pose JSON files; mrcal's
// Python poseutils as an independent reference for compose/invert.
#include <clearfit/camera/pose_file.hpp>
#include <clearfit/error.hpp>

#include "../support/outside_tools.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <unistd.h>

namespace clearfit {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = std::numbers::pi;

Eigen::Matrix3d angle_axis(double angle, Eigen::Vector3d axis) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

class TempDir : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("clearfit_pose_" + std::to_string(::getpid()) + "_" + info->test_suite_name() + "_" + info->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path file(const std::string& name, const std::string& text) const {
    std::ofstream(dir_ / name) << text;
    return dir_ / name;
  }
  fs::path dir_;
};

TEST(Rigid3, HalfPiAboutZMatchesClosedForm) {
  const Rigid3 t = Rigid3::from_rt({0, 0, kPi / 2, 1, 2, 3});
  Eigen::Matrix3d expected;
  expected << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_LT((t.rotation - expected).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((t.apply({1, 0, 0}) - Eigen::Vector3d(1, 3, 3)).norm(), 1e-15);  // x -> y, then + t
}

TEST(Rigid3, PiAboutXAndTwoHalfTurnsCompose) {
  const Rigid3 rx = Rigid3::from_rt({kPi, 0, 0, 0, 0, 0});
  EXPECT_LT((rx.rotation - Eigen::Vector3d(1, -1, -1).asDiagonal().toDenseMatrix()).cwiseAbs().maxCoeff(), 1e-15);
  const Rigid3 qz = Rigid3::from_rt({0, 0, kPi / 2, 0, 0, 0});
  const auto r = (qz * qz).to_rt();
  EXPECT_NEAR(std::abs(r[2]), kPi, 1e-15);  // +pi or -pi about z: the same rotation
  EXPECT_NEAR(r[0], 0, 1e-15);
  EXPECT_NEAR(r[1], 0, 1e-15);
}

TEST(Rigid3, RodriguesMatchesAngleAxisOverRandomRotations) {
  const unsigned seed = 20261122;
  std::printf("seed %u\n", seed);
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss;
  std::uniform_real_distribution<double> angle(0, kPi);
  for (int k = 0; k < 2000; ++k) {
    const Eigen::Vector3d axis = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    double theta = angle(rng);
    if (k % 10 == 1) theta = std::pow(10.0, -1 - (k % 13));       // tiny angles down to 1e-13
    if (k % 10 == 2) theta = kPi - std::pow(10.0, -1 - (k % 11));  // near pi
    const Eigen::Matrix3d expected = angle_axis(theta, axis);
    const Eigen::Matrix3d r = rotation_from_rodrigues(theta * axis);
    ASSERT_LT((r - expected).cwiseAbs().maxCoeff(), 2e-15) << "k " << k << " theta " << theta;
    const Eigen::Vector3d back = rodrigues_from_rotation(expected);
    ASSERT_LE(back.norm(), kPi + 1e-15);
    // Near pi the vector is ill-conditioned; compare the rotations it gives.
    ASSERT_LT((rotation_from_rodrigues(back) - expected).cwiseAbs().maxCoeff(), 4e-15) << "k " << k;
    if (theta < kPi - 1e-3) ASSERT_LT((back - theta * axis).norm(), 4e-15 * std::max(1.0, theta)) << "k " << k;
  }
}

TEST(Rigid3, TinyRotationKeepsRelativePrecision) {
  const Eigen::Vector3d r(3e-12, -1e-12, 2e-12);
  const Eigen::Vector3d back = rodrigues_from_rotation(rotation_from_rodrigues(r));
  EXPECT_LT((back - r).norm(), 1e-26);
  EXPECT_EQ(rodrigues_from_rotation(Eigen::Matrix3d::Identity()), Eigen::Vector3d::Zero());
}

TEST(Rigid3, ComposeAndInverseIdentities) {
  const Rigid3 a = Rigid3::from_rt({0.3, -0.2, 0.9, 10, -5, 120});
  const Rigid3 b = Rigid3::from_rt({-1.1, 0.4, 0.05, -3, 7, 0.5});
  const Eigen::Vector3d x(1.5, -2.25, 40);
  EXPECT_LT(((a * b).apply(x) - a.apply(b.apply(x))).norm(), 1e-12);
  EXPECT_LT((a.inverse().apply(a.apply(x)) - x).norm(), 1e-12);
  const Rigid3 i = a * a.inverse();
  EXPECT_LT((i.rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT(i.translation.norm(), 1e-13);
  const Rigid3 lhs = (a * b).inverse(), rhs = b.inverse() * a.inverse();
  EXPECT_LT((lhs.rotation - rhs.rotation).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((lhs.translation - rhs.translation).norm(), 1e-12);
  EXPECT_LT((a.apply_direction(x) - a.rotation * x).norm(), 0.0 + 1e-15);
}

TEST_F(TempDir, ComposeAndInvertMatchMrcalPython) {
  CLEARFIT_REQUIRE_PYTHON("mrcal", "python3-mrcal");
  const std::array<double, 6> a{0.3, -0.2, 0.9, 10, -5, 120}, b{-1.1, 0.4, 2.5, -3, 7, 0.5};
  const auto script = file("ref.py",
                           "import sys, json, numpy as np, mrcal\n"
                           "a = np.array(json.loads(sys.argv[1])); b = np.array(json.loads(sys.argv[2]))\n"
                           "print(json.dumps({'ab': mrcal.compose_rt(a, b).tolist(),"
                           " 'ainv': mrcal.invert_rt(a).tolist()}))\n");
  const auto out = dir_ / "out.json";
  const std::string cmd = "/usr/bin/python3 " + script.string() + " '" + nlohmann::json(a).dump() + "' '" +
                          nlohmann::json(b).dump() + "' > " + out.string();
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  const auto ref = nlohmann::json::parse(std::ifstream(out));
  // mrcal's compose_rt may return an angle above pi (the same rotation about
  // the opposite axis), so compare the transforms, not the vectors.
  const auto as_rigid = [](const nlohmann::json& rt) {
    std::array<double, 6> v;
    for (int k = 0; k < 6; ++k) v[k] = rt[k].get<double>();
    return Rigid3::from_rt(v);
  };
  const Rigid3 ab = Rigid3::from_rt(a) * Rigid3::from_rt(b), ab_ref = as_rigid(ref["ab"]);
  const Rigid3 ainv = Rigid3::from_rt(a).inverse(), ainv_ref = as_rigid(ref["ainv"]);
  EXPECT_LT((ab.rotation - ab_ref.rotation).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_LT((ab.translation - ab_ref.translation).norm(), 1e-12);
  EXPECT_LT((ainv.rotation - ainv_ref.rotation).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_LT((ainv.translation - ainv_ref.translation).norm(), 1e-12);
  // invert_rt keeps the angle: its vector must match ours exactly up to rounding.
  const auto ainv_rt = ainv.to_rt();
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(ainv_rt[k], ref["ainv"][k].get<double>(), 1e-12) << k;
}

TEST_F(TempDir, PoseJsonRoundTrip) {
  const Rigid3 pose = Rigid3::from_rt({0.1, -2.0, 0.7, 12.5, -3.25, 250});
  const auto path = dir_ / "pose.json";
  write_pose_json(pose, path);
  const auto j = nlohmann::json::parse(std::ifstream(path));
  EXPECT_EQ(j["schema"], "clearfit.pose/1");
  EXPECT_EQ(j["units"], "mm");
  const Rigid3 back = read_pose_json(path);
  EXPECT_LT((back.rotation - pose.rotation).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(back.translation, pose.translation);  // written at full precision
  int files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_)) ++files;
  EXPECT_EQ(files, 1) << "a temporary file was left behind";
}

void expect_pose_error(const fs::path& path, const std::string& element_part, const std::string& message_part) {
  try {
    read_pose_json(path);
    ADD_FAILURE() << "no error for " << path;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), path.string());
    EXPECT_NE(e.element().find(element_part), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(message_part), std::string::npos) << e.what();
  }
}

TEST_F(TempDir, PoseJsonErrorsAreLocated) {
  expect_pose_error(dir_ / "missing.json", "", "cannot open");
  expect_pose_error(file("syntax.json", "{\n  \"schema\": \"clearfit.pose/1\",\n  \"units\": mm\n}"), "line 3",
                    "not valid JSON");
  expect_pose_error(file("schema.json", R"({"schema":"other/2","units":"mm","cam_from_part":{"r":[0,0,0],"t":[0,0,0]}})"),
                    "schema", "clearfit.pose/1");
  expect_pose_error(file("units.json", R"({"schema":"clearfit.pose/1","units":"m","cam_from_part":{"r":[0,0,0],"t":[0,0,0]}})"),
                    "units", "mm");
  expect_pose_error(file("short.json", R"({"schema":"clearfit.pose/1","units":"mm","cam_from_part":{"r":[0,0,0],"t":[0,0]}})"),
                    "cam_from_part.t", "3 numbers");
  expect_pose_error(file("nor.json", R"({"schema":"clearfit.pose/1","units":"mm","cam_from_part":{"t":[0,0,1]}})"),
                    "cam_from_part.r", "missing");
  expect_pose_error(file("str.json", R"({"schema":"clearfit.pose/1","units":"mm","cam_from_part":{"r":[0,"a",0],"t":[0,0,1]}})"),
                    "cam_from_part.r", "finite numbers");
}

TEST_F(TempDir, PoseJsonCarriesItsCovariance) {
  const Rigid3 pose = Rigid3::from_rt({0.1, -2.0, 0.7, 12.5, -3.25, 250});
  Eigen::Matrix<double, 6, 6> a = Eigen::Matrix<double, 6, 6>::Random();
  const PoseCovariance cov = 1e-4 * a * a.transpose();
  write_pose_json(pose, dir_ / "with.json", cov);
  const PoseFile back = read_pose_file(dir_ / "with.json");
  ASSERT_TRUE(back.covariance.has_value());
  EXPECT_LT((*back.covariance - cov).cwiseAbs().maxCoeff(), 1e-15);
  // The 1-σ beside it, for people: √ of the diagonal, rotation in degrees.
  const auto j = nlohmann::json::parse(std::ifstream(dir_ / "with.json"));
  EXPECT_NEAR(j["sigma"]["rotation_deg"][1].get<double>(), std::sqrt(cov(1, 1)) * 180 / M_PI, 1e-12);
  EXPECT_NEAR(j["sigma"]["translation_mm"][2].get<double>(), std::sqrt(cov(5, 5)), 1e-12);
  // Without: none; with only "sigma": independent axes.
  write_pose_json(pose, dir_ / "without.json");
  EXPECT_FALSE(read_pose_file(dir_ / "without.json").covariance.has_value());
  const auto only = read_pose_file(file("sigma.json", R"({"schema":"clearfit.pose/1","units":"mm","cam_from_part":{"r":[0,0,0],"t":[0,0,100]},
    "sigma":{"rotation_deg":[0.1,0.2,0.3],"translation_mm":[0.01,0.02,0.5]}})"));
  ASSERT_TRUE(only.covariance.has_value());
  EXPECT_NEAR((*only.covariance)(1, 1), std::pow(0.2 * M_PI / 180, 2), 1e-18);
  EXPECT_NEAR((*only.covariance)(5, 5), 0.25, 1e-15);
  EXPECT_EQ((*only.covariance)(0, 3), 0.0);
}

TEST_F(TempDir, PoseJsonUncertaintyErrorsAreLocated) {
  const std::string head = R"({"schema":"clearfit.pose/1","units":"mm","cam_from_part":{"r":[0,0,0],"t":[0,0,100]},)";
  expect_pose_error(file("negsigma.json", head + R"("sigma":{"rotation_deg":[0.1,-0.2,0.3],"translation_mm":[0,0,0]}})"), "sigma",
                    "0 or more");
  expect_pose_error(file("nosigmat.json", head + R"("sigma":{"rotation_deg":[0.1,0.2,0.3]}})"), "sigma.translation_mm", "missing");
  expect_pose_error(file("short.json", head + R"("covariance":[[1,0,0,0,0,0]]})"), "covariance", "6 rows");
  expect_pose_error(file("asym.json", head + R"("covariance":[[1,0.5,0,0,0,0],[0,1,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,0,1]]})"),
                    "covariance", "symmetric");
  expect_pose_error(file("negdiag.json", head + R"("covariance":[[-1,0,0,0,0,0],[0,1,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,0,1]]})"),
                    "covariance", "non-negative");
  expect_pose_error(file("text.json", head + R"("covariance":[[1,0,0,0,0,"x"],[0,1,0,0,0,0],[0,0,1,0,0,0],[0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,0,1]]})"),
                    "'covariance' row 1", "finite");
}

}  // namespace
}  // namespace clearfit
