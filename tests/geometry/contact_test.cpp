// Contact-surface selection: by group, by face file, by normal cone; bad input.
#include <clearfit/error.hpp>
#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

using namespace clearfit;
using ::testing::HasSubstr;

namespace {
std::filesystem::path temp_file(const std::string& name, const std::string& text) {
  auto p = std::filesystem::temp_directory_path() / ("clearfit_contact_" + name);
  std::ofstream(p) << text;
  return p;
}
}  // namespace

TEST(Contact, ByGroupMatchesClosedFormArea) {
  Mesh m = shapes::slab(20, 10, 2, 4);
  ContactSelector s;
  s.group = "contact";
  ContactSurface c = select_contact(m, s);
  EXPECT_EQ(c.faces.size(), 32u);
  EXPECT_NEAR(c.area_mm2, 200, 1e-10);
  EXPECT_EQ(c.components, 1);
}

TEST(Contact, ByNormalConeOnABand) {
  Mesh m = shapes::cylindrical_shell(30, 32, 60, 10, 30, 2);
  ContactSelector s;
  s.normal = Vec3(0, 0, -1);  // the inner surface near the middle faces -z
  s.angle_deg = 15.5;
  ContactSurface c = select_contact(m, s);
  // 2° segments centred at ±1°, ±3°, ..., ±29°: those within 15.5° are the 16
  // centred at ±1..±15, each 2 quads along the width, 2 triangles each.
  EXPECT_EQ(c.faces.size(), 16u * 2 * 2);
  EXPECT_EQ(c.components, 1);
}

TEST(Contact, ByFaceFileInFileOrderAndComponents) {
  Mesh m = shapes::box({1, 1, 1}, 1);
  auto p = temp_file("ok.txt", "0 1  # xmin\n3\n2\n");
  ContactSelector s;
  s.face_file = p;
  ContactSurface c = select_contact(m, s);
  EXPECT_EQ(c.faces, (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(c.components, 2);  // xmin and xmax: opposite sides of the box
  EXPECT_NEAR(c.area_mm2, 2, 1e-12);
}

TEST(Contact, BadInputNamesTheProblem) {
  Mesh m = shapes::box({1, 1, 1}, 1);
  ContactSelector none;
  EXPECT_THROW(select_contact(m, none), InputError);
  ContactSelector g;
  g.group = "skin";
  try {
    select_contact(m, g);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("'skin'"));
    EXPECT_THAT(e.what(), HasSubstr("'xmin'"));
  }
  for (auto [text, needle] : {std::pair{"0 1 x2\n", "line 1, 'x2'"}, {"0\n-3\n", "line 2, '-3'"},
                              {"12\n", "out of range"}}) {
    ContactSelector f;
    f.face_file = temp_file("bad.txt", text);
    try {
      select_contact(m, f);
      FAIL() << text;
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr(needle));
      EXPECT_THAT(e.what(), HasSubstr("bad.txt"));
    }
  }
  ContactSelector missing;
  missing.face_file = "/nonexistent/faces.txt";
  EXPECT_THROW(select_contact(m, missing), InputError);
  ContactSelector cone;
  cone.normal = Vec3(0, 0, 0);
  EXPECT_THROW(select_contact(m, cone), InputError);
  cone.normal = Vec3(1, 1, 1);
  cone.angle_deg = 1;  // no box face within 1° of the diagonal
  EXPECT_THROW(select_contact(m, cone), InputError);
}
