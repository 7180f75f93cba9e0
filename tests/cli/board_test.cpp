// End-to-end tests of `clearfit board` and `clearfit detect`: an SVG at exact
// physical size, the board file, bad options (exit 2, nothing written).
#include "cli_support.hpp"

#include <regex>

namespace clearfit::cli_test {
namespace {

class BoardCli : public CliTest {};

TEST_F(BoardCli, SvgHasExactMillimetreSize) {
  const RunResult r = run({"board", "--rows", "3", "--cols", "4", "--tag-mm", "25", "--gap-mm", "25", "--out",
                           "b.svg", "--board-file", "b.yaml"});
  ASSERT_EQ(r.exit_code, 0) << r;
  const std::string svg = read_text(work() / "b.svg");
  // 4 tags of 25 mm + 3 gaps of 25 mm = 175 mm of black squares; margin = max(2 cells + 1 cell, gap/2) = 12.5
  // mm.
  const double w = 175 + 2 * 12.5, h = 125 + 2 * 12.5 + 24;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      svg, m,
      std::regex(
          R"re(<svg[^>]*width="([0-9.]+)mm" height="([0-9.]+)mm" viewBox="0 0 ([0-9.]+) ([0-9.]+)")re")))
      << svg.substr(0, 400);
  EXPECT_DOUBLE_EQ(std::stod(m[1]), w);
  EXPECT_DOUBLE_EQ(std::stod(m[2]), h);
  EXPECT_DOUBLE_EQ(std::stod(m[3]), w);  // 1 user unit = 1 mm
  EXPECT_DOUBLE_EQ(std::stod(m[4]), h);
  // One group per tag, ids 0..11; a 100 mm scale bar with its label.
  const std::regex tag_group("<g id=\"tag[0-9]+\">");
  EXPECT_EQ(std::distance(std::sregex_iterator(svg.begin(), svg.end(), tag_group), std::sregex_iterator()),
            12);
  EXPECT_NE(svg.find("x2=\"110\""), std::string::npos);  // bar from x = 10 to 110 mm
  EXPECT_NE(svg.find(">100 mm<"), std::string::npos);
  EXPECT_NE(svg.find("tag36h11, 3 x 4 tags of 25 mm"), std::string::npos);
  const std::string yaml = read_text(work() / "b.yaml");
  EXPECT_NE(yaml.find("schema: clearfit.board/1"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("grid_width: 8"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("spacing_mm: 25"), std::string::npos) << yaml;
}

TEST_F(BoardCli, BadOptionsExitTwoAndWriteNothing) {
  expect_input_error({"board", "--gap-mm", "7.77", "--out", "b.svg"}, {"--gap-mm", "one uniform grid"});
  expect_input_error({"board", "--rows", "0", "--out", "b.svg"}, {"--rows"});
  expect_input_error({"board", "--family", "tagStandard41h12", "--out", "b.svg"}, {"--family"});
  expect_input_error({"board", "--first-id", "580", "--board-file", "b.yaml"}, {"--first-id"});
  expect_input_error({"board", "--out", "b.pdf"}, {"--out", "svg"});
  expect_input_error({"board"}, {"nothing to write"});
  expect_input_error({"board", "--rows", "two", "--out", "b.svg"}, {"--rows"});
}

TEST_F(BoardCli, DetectWritesCornersVnl) {
  const std::string data = std::string(CLEARFIT_TEST_DATA_DIR) + "/boards/";
  ASSERT_EQ(
      run({"board", "--rows", "3", "--cols", "4", "--first-id", "10", "--board-file", "b.yaml"}).exit_code,
      0);
  const RunResult r = run({"detect", "--board", "b.yaml", data + "pose_fixture.png", "--out", "corners.vnl"});
  ASSERT_EQ(r.exit_code, 0) << r;
  EXPECT_NE(r.err.find("detecting: 1/1 images"), std::string::npos) << r;
  EXPECT_NE(r.out.find("12 tags, 48/48 corners"), std::string::npos) << r;
  const std::string vnl = read_text(work() / "corners.vnl");
  EXPECT_EQ(vnl.rfind("# filename x y weight\n", 0), 0u);
  EXPECT_EQ(std::count(vnl.begin(), vnl.end(), '\n'), 1 + 8 * 6);  // grid 8 x 6
  // The wrong board: found in no image, exit 2, no corners file.
  ASSERT_EQ(run({"board", "--rows", "3", "--cols", "4", "--first-id", "100", "--board-file", "other.yaml"})
                .exit_code,
            0);
  expect_input_error({"detect", "--board", "other.yaml", data + "pose_fixture.png", "--out", "c2.vnl"},
                     {"none of the 1 images"});
  expect_input_error({"detect", "--board", "missing.yaml", data + "pose_fixture.png", "--out", "c3.vnl"},
                     {"missing.yaml"});
}

}  // namespace
}  // namespace clearfit::cli_test
