// Board layouts on mrcal's uniform grid, corner mapping, board files.
#include <clearfit/camera/board.hpp>
#include <clearfit/camera/detect.hpp>
#include <clearfit/camera/tag_pose.hpp>
#include <clearfit/error.hpp>

#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <regex>
#include <set>

namespace clearfit {
namespace {

namespace fs = std::filesystem;

/// The geometric corner k of a tag (AprilTag order, board frame, y down),
/// computed from the layout alone.
Eigen::Vector3d expected_corner(const Board& b, int id, int k) {
  const Eigen::Vector2d o = b.tag_origin_mm(id);
  const double t = b.layout.tag_mm;
  const Eigen::Vector2d off[4] = {
      {0, t}, {t, t}, {t, 0}, {0, 0}};  // bottom-left, bottom-right, top-right, top-left
  return {o.x() + off[k].x(), o.y() + off[k].y(), 0};
}

void expect_consistent(const Board& b) {
  std::set<int> used;
  for (int id = b.layout.first_id; id < b.layout.first_id + b.num_tags(); ++id)
    for (int k = 0; k < 4; ++k) {
      const auto g = b.corner_grid_index(id, k);
      ASSERT_TRUE(g);
      ASSERT_GE(g->row, 0);
      ASSERT_LT(g->row, b.grid_height);
      ASSERT_GE(g->col, 0);
      ASSERT_LT(g->col, b.grid_width);
      EXPECT_LT((b.point_mm(*g) - expected_corner(b, id, k)).norm(), 1e-9) << "tag " << id << " corner " << k;
      EXPECT_TRUE(used.insert(b.point_index(*g)).second) << "two corners on one node";
      const auto back = b.tag_corner_at(*g);
      ASSERT_TRUE(back);
      EXPECT_EQ(back->first, id);
      EXPECT_EQ(back->second, k);
    }
  int corner_nodes = 0;
  for (int i = 0; i < b.grid_height; ++i)
    for (int j = 0; j < b.grid_width; ++j) corner_nodes += b.tag_corner_at({i, j}).has_value();
  EXPECT_EQ(corner_nodes, 4 * b.num_tags());
  const auto pts = b.points_mm();
  ASSERT_EQ(pts.size(), static_cast<std::size_t>(b.num_points()));
  EXPECT_EQ(pts[1], Eigen::Vector3d(b.spacing_mm, 0, 0));
  EXPECT_EQ(pts[static_cast<std::size_t>(b.grid_width)], Eigen::Vector3d(0, b.spacing_mm, 0));
}

TEST(Board, RecommendedLayoutIsTwoNodesPerTag) {
  const Board b = make_board({"tag36h11", 6, 8, 20.0, 20.0, 3});
  EXPECT_EQ(b.grid_width, 16);
  EXPECT_EQ(b.grid_height, 12);
  EXPECT_DOUBLE_EQ(b.spacing_mm, 20.0);
  EXPECT_EQ(b.cells_at_border, 8);
  EXPECT_EQ(b.cells_total, 10);
  EXPECT_DOUBLE_EQ(b.width_mm(), 8 * 20 + 7 * 20);
  EXPECT_EQ(*b.corner_grid_index(3, 3), (GridIndex{0, 0}));         // tag 3 = top-left tag, corner top-left
  EXPECT_EQ(*b.corner_grid_index(3 + 47, 1), (GridIndex{11, 15}));  // last tag, bottom-right
  EXPECT_FALSE(b.corner_grid_index(2, 0));
  EXPECT_FALSE(b.corner_grid_index(51, 0));
  EXPECT_THROW(b.corner_grid_index(3, 4), std::invalid_argument);
  expect_consistent(b);
  EXPECT_EQ(describe(b),
            "tag36h11, 6 x 8 tags of 20 mm, gap 20 mm, ids 3..50; grid 16 x 12 points, spacing 20 mm");
}

TEST(Board, FractionalGapsGiveAFinerGridWithEmptyNodes) {
  for (const auto& [tag, gap, spacing, width] : {std::tuple{24.0, 12.0, 12.0, 168 / 12 + 1},
                                                 {24.0, 6.0, 6.0, 144 / 6 + 1},
                                                 {30.0, 45.0, 15.0, 330 / 15 + 1}}) {
    const Board b = make_board({"tag36h11", 3, 5, tag, gap, 0});
    EXPECT_DOUBLE_EQ(b.spacing_mm, spacing) << tag << " " << gap;
    EXPECT_EQ(b.grid_width, width) << tag << " " << gap;
    EXPECT_NEAR(b.width_mm(), 5 * tag + 4 * gap, 1e-9);
    expect_consistent(b);
  }
}

TEST(Board, LayoutsOffTheGridAreRefused) {
  auto element_of = [](const BoardLayout& l) {
    try {
      make_board(l);
    } catch (const InputError& e) {
      return e.element();
    }
    return std::string("accepted");
  };
  EXPECT_EQ(element_of({"tag36h11", 4, 5, 20.0, 20.0 * std::sqrt(2.0), 0}), "gap_mm");  // not commensurate
  EXPECT_EQ(element_of({"tag36h11", 4, 5, 20.0, 2.0, 0}), "gap_mm");  // narrower than a cell (2.5)
  EXPECT_EQ(element_of({"tag36h11", 0, 5, 20.0, 20.0, 0}), "rows");
  EXPECT_EQ(element_of({"tag36h11", 4, -1, 20.0, 20.0, 0}), "cols");
  EXPECT_EQ(element_of({"tag36h11", 4, 5, NAN, 20.0, 0}), "tag_mm");
  EXPECT_EQ(element_of({"tag99h1", 4, 5, 20.0, 20.0, 0}), "family");
  EXPECT_EQ(element_of({"tagStandard41h12", 4, 5, 20.0, 20.0, 0}), "family");  // reversed border
  EXPECT_EQ(element_of({"tag16h5", 6, 6, 20.0, 20.0, 0}), "first_id");         // 30 codes only
  EXPECT_EQ(element_of({"tag36h11", 4, 5, 20.0, 20.0, 580}), "first_id");
  EXPECT_EQ(element_of({"tag25h9", 4, 5, 20.0, 20.0, 0}), "accepted");
  try {
    make_board({"tag36h11", 4, 5, 20.0, 21.3, 0});
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("one uniform grid"), std::string::npos) << e.what();
  }
}

TEST(Board, TagCellsHaveTheBordersOfTheFamily) {
  const Board b = make_board({"tag36h11", 2, 2, 20.0, 20.0, 0});
  const auto c0 = tag_cells(b, 0), c1 = tag_cells(b, 1);
  ASSERT_EQ(c0.size(), 100u);
  for (int i = 0; i < 10; ++i) {
    EXPECT_EQ(c0[i], 1);                             // white outer ring (top row)
    EXPECT_EQ(c0[90 + i], 1);                        // bottom row
    if (i >= 1 && i <= 8) {
      EXPECT_EQ(c0[10 + i], 0);  // black ring
    }
  }
  EXPECT_NE(c0, c1);
  EXPECT_THROW(tag_cells(b, 4), std::invalid_argument);
}

TEST(Board, PrintedSvgIsDetectedWhereTheLayoutSaysWhenRasterised) {
  // Rasterise the SVG's black rectangles at 8 px/mm (every cell edge on a pixel
  // edge) and detect it: every tag found, corners where the layout puts them.
  const Board b = make_board({"tag36h11", 2, 3, 10.0, 10.0, 5});
  const std::string svg = board_svg(b);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(svg, m, std::regex(R"re(width="([0-9.]+)mm" height="([0-9.]+)mm")re")));
  const double page_w = std::stod(m[1]), page_h = std::stod(m[2]), s = 8;
  cv::Mat img(static_cast<int>(page_h * s), static_cast<int>(page_w * s), CV_8UC1, cv::Scalar(255));
  const std::string tags = svg.substr(svg.find("<g id=\"tags\""));
  const std::regex rect(R"re(<rect x="([0-9.]+)" y="([0-9.]+)" width="([0-9.]+)" height="([0-9.]+)"/>)re");
  int rects = 0;
  for (auto it = std::sregex_iterator(tags.begin(), tags.end(), rect); it != std::sregex_iterator();
       ++it, ++rects) {
    const auto& r = *it;
    const cv::Point p0(static_cast<int>(std::lround(std::stod(r[1]) * s)),
                       static_cast<int>(std::lround(std::stod(r[2]) * s)));
    const cv::Point p1(static_cast<int>(std::lround((std::stod(r[1]) + std::stod(r[3])) * s)),
                       static_cast<int>(std::lround((std::stod(r[2]) + std::stod(r[4])) * s)));
    img(cv::Rect(p0, p1)).setTo(0);
  }
  EXPECT_GT(rects, 6 * 8);
  cv::GaussianBlur(img, img, cv::Size(0, 0), 0.7);
  const BoardObservation o = detect_board(img, b);
  EXPECT_EQ(o.tags_used, 6);
  const double x0 = (page_w - b.width_mm()) / 2, y0 = b.margin_mm();
  for (int i = 0; i < b.grid_height; ++i)
    for (int j = 0; j < b.grid_width; ++j) {
      const Eigen::Vector3d& c = o.corners[static_cast<std::size_t>(b.point_index({i, j}))];
      ASSERT_GE(c.z(), 0);
      const Eigen::Vector3d p = b.point_mm({i, j});
      EXPECT_NEAR(c.x(), (x0 + p.x()) * s - 0.5, 0.05) << i << " " << j;
      EXPECT_NEAR(c.y(), (y0 + p.y()) * s - 0.5, 0.05) << i << " " << j;
    }
}

class BoardFile : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("clearfit_board_" + std::to_string(::getpid()));
  void SetUp() override { fs::create_directories(dir); }
  void TearDown() override { fs::remove_all(dir); }
  fs::path write(const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return dir / name;
  }
  std::string error_of(const fs::path& p) {
    try {
      read_board(p);
    } catch (const InputError& e) {
      return e.what();
    }
    return "accepted";
  }
};

TEST_F(BoardFile, RoundTrip) {
  const Board b = make_board({"tag25h9", 3, 4, 17.5, 8.75, 7});
  write_board(b, dir / "b.yaml");
  const Board r = read_board(dir / "b.yaml");
  EXPECT_EQ(r.layout.family, "tag25h9");
  EXPECT_EQ(r.layout.rows, 3);
  EXPECT_EQ(r.layout.cols, 4);
  EXPECT_EQ(r.layout.tag_mm, 17.5);
  EXPECT_EQ(r.layout.gap_mm, 8.75);
  EXPECT_EQ(r.layout.first_id, 7);
  EXPECT_EQ(r.grid_width, b.grid_width);
  EXPECT_EQ(r.spacing_mm, b.spacing_mm);
}

TEST_F(BoardFile, JsonIsReadToo) {
  const auto p =
      write("b.json", R"({"schema": "clearfit.board/1", "rows": 2, "cols": 3, "tag_mm": 30, "gap_mm": 30})");
  const Board b = read_board(p);
  EXPECT_EQ(b.layout.family, "tag36h11");
  EXPECT_EQ(b.grid_width, 6);
}

TEST_F(BoardFile, BadFilesNameTheKeyAndLine) {
  const std::string head = "schema: clearfit.board/1\nrows: 2\ncols: 3\ntag_mm: 30\n";
  EXPECT_NE(error_of(write("a.yaml", head + "gap_mm: 30\ncolour: red\n")).find("key 'colour' (line 6)"),
            std::string::npos);
  EXPECT_NE(error_of(write("b.yaml", head)).find("key 'gap_mm': missing"), std::string::npos);
  EXPECT_NE(error_of(write("c.yaml", head + "gap_mm: wide\n")).find("key 'gap_mm' (line 5): wrong type"),
            std::string::npos);
  EXPECT_NE(error_of(write("d.yaml", head + "gap_mm: 30\ngrid_width: 8\n")).find("disagrees"),
            std::string::npos);
  EXPECT_NE(error_of(write("e.yaml", head + "gap_mm: 31\n")).find("key 'gap_mm' (line 5)"),
            std::string::npos);
  EXPECT_NE(error_of(write("f.yaml", "schema: clearfit.board/2\n")).find("clearfit.board/1"),
            std::string::npos);
  EXPECT_NE(error_of(write("g.yaml", "rows: [1,\n")).find("line"), std::string::npos);
  EXPECT_NE(error_of(dir / "missing.yaml").find("not found"), std::string::npos);
  // yaml-cpp's own exception (exit 1) for a key that is a list, until fuzzing showed it.
  EXPECT_NE(error_of(write("h.yaml", head + "[gap_mm]: 30\n")).find("h.yaml: line 5: a key is a list, a map or empty"),
            std::string::npos);
}

// Every input kept in fuzz/regressions/{board,tag_layout}/ (found while fuzzing) is
// read or refused with an InputError naming the file, and nothing else.
TEST_F(BoardFile, FuzzRegressionInputsAreReadOrRefused) {
  const fs::path root = fs::path(CLEARFIT_TEST_DATA_DIR) / ".." / ".." / "fuzz" / "regressions";
  int inputs = 0;
  for (const std::string format : {"board", "tag_layout"}) {
    if (!fs::is_directory(root / format)) continue;
    for (const auto& entry : fs::directory_iterator(root / format)) {
      SCOPED_TRACE(entry.path().string());
      ++inputs;
      try {
        if (format == "board") read_board(entry.path());
        else read_tag_layout(entry.path());
      } catch (const InputError& e) {
        EXPECT_EQ(e.file(), entry.path().string()) << e.what();
      }
    }
  }
  EXPECT_GT(inputs, 0) << "no regression inputs under " << root;
}

}  // namespace
}  // namespace clearfit
