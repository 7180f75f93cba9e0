// AprilTag board layouts on mrcal's uniform grid; board files.
#include <clearfit/atomic_file.hpp>
#include <clearfit/camera/board.hpp>
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>
#include <clearfit/yaml_key.hpp>

#include "apriltag_family_internal.hpp"

#include <apriltag/common/image_u8.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h10.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <set>
#include <sstream>
#include <stdexcept>

namespace clearfit {

namespace detail {

namespace {
struct FamilyEntry {
  const char* name;
  apriltag_family_t* (*create)();
  void (*destroy)(apriltag_family_t*);
};
const FamilyEntry kFamilies[] = {
    {"tag36h11", tag36h11_create, tag36h11_destroy},
    {"tag36h10", tag36h10_create, tag36h10_destroy},
    {"tag25h9", tag25h9_create, tag25h9_destroy},
    {"tag16h5", tag16h5_create, tag16h5_destroy},
    {"tagCircle21h7", tagCircle21h7_create, tagCircle21h7_destroy},
    {"tagCircle49h12", tagCircle49h12_create, tagCircle49h12_destroy},
    {"tagCustom48h12", tagCustom48h12_create, tagCustom48h12_destroy},
    {"tagStandard41h12", tagStandard41h12_create, tagStandard41h12_destroy},
    {"tagStandard52h13", tagStandard52h13_create, tagStandard52h13_destroy},
};
}  // namespace

FamilyPtr create_family(const std::string& name) {
  for (const auto& f : kFamilies)
    if (name == f.name) return FamilyPtr(f.create(), FamilyDeleter{f.destroy});
  return FamilyPtr(nullptr, FamilyDeleter{});
}

const std::vector<std::string>& family_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const auto& f : kFamilies) n.emplace_back(f.name);
    return n;
  }();
  return names;
}

bool family_has_classic_border(const apriltag_family_t& family) {
  return !family.reversed_border && family.total_width == family.width_at_border + 2;
}

}  // namespace detail

namespace {

/// Smallest q in 1..16 with ratio * q an integer (to 1e-6 relative); 0 if none.
int denominator_of(double ratio) {
  for (int q = 1; q <= 16; ++q) {
    const double pq = ratio * q;
    if (std::abs(pq - std::round(pq)) <= 1e-6 * std::max(1.0, pq)) return q;
  }
  return 0;
}

}  // namespace

Board make_board(const BoardLayout& layout) {
  Board b;
  b.layout = layout;
  if (layout.rows < 1) throw InputError("", "rows", "must be at least 1, got " + std::to_string(layout.rows));
  if (layout.cols < 1) throw InputError("", "cols", "must be at least 1, got " + std::to_string(layout.cols));
  if (layout.rows * static_cast<long>(layout.cols) > 100000)
    throw InputError("", "rows x cols", "more than 100000 tags", "a calibration board has tens of tags");
  if (!(std::isfinite(layout.tag_mm) && layout.tag_mm > 0))
    throw InputError(
        "", "tag_mm",
        "must be a positive edge of the black square in mm, got " + significant_digits(layout.tag_mm, 10));
  if (!(std::isfinite(layout.gap_mm) && layout.gap_mm >= 0))
    throw InputError("", "gap_mm",
                     "must be a finite gap in mm >= 0, got " + significant_digits(layout.gap_mm, 10));
  if (layout.first_id < 0)
    throw InputError("", "first_id", "must be >= 0, got " + std::to_string(layout.first_id));

  const detail::FamilyPtr family = detail::create_family(layout.family);
  if (!family) {
    std::string known;
    for (const auto& n : detail::family_names()) known += (known.empty() ? "" : ", ") + n;
    throw InputError("", "family", "unknown AprilTag family '" + layout.family + "'", "one of " + known);
  }
  if (!detail::family_has_classic_border(*family))
    throw InputError("", "family",
                     "'" + layout.family +
                         "' has no plain outer black border (its detected square lies inside the "
                         "tag), so its corners do not sit where the board grid puts them",
                     "use tag36h11 (or tag36h10, tag25h9, tag16h5)");
  b.cells_at_border = family->width_at_border;
  b.cells_total = family->total_width;
  b.family_codes = static_cast<int>(family->ncodes);
  if (static_cast<long>(layout.first_id) + b.num_tags() > b.family_codes)
    throw InputError(
        "", "first_id",
        "ids " + std::to_string(layout.first_id) + ".." + std::to_string(layout.first_id + b.num_tags() - 1) +
            " do not exist: " + layout.family + " has ids 0.." + std::to_string(b.family_codes - 1),
        "lower first_id or use fewer tags");

  const double cell = layout.tag_mm / b.cells_at_border;
  if (layout.gap_mm < cell * (1 - 1e-9))
    throw InputError("", "gap_mm",
                     "gap " + significant_digits(layout.gap_mm, 10) + " mm is narrower than one bit cell (" +
                         significant_digits(cell, 10) +
                         " mm): the tags' white borders would overlap and AprilTag cannot find them",
                     "use gap_mm = tag_mm (" + significant_digits(layout.tag_mm, 10) +
                         "), which also gives the simplest grid");
  // Both lengths must be integer multiples of one spacing: gap/tag = p/q.
  const int q = denominator_of(layout.gap_mm / layout.tag_mm);
  if (q == 0)
    throw InputError(
        "", "gap_mm",
        "tag " + significant_digits(layout.tag_mm, 10) + " mm and gap " +
            significant_digits(layout.gap_mm, 10) +
            " mm are not multiples of one spacing, so the tag corners do not lie on one uniform grid "
            "(mrcal's board model)",
        "use gap_mm = tag_mm, or a gap that is a simple fraction of the tag (e.g. tag/2, tag/4)");
  b.nodes_per_tag = q;
  b.spacing_mm = layout.tag_mm / q;
  b.nodes_per_pitch = q + static_cast<int>(std::lround(layout.gap_mm / b.spacing_mm));
  b.grid_width = (layout.cols - 1) * b.nodes_per_pitch + b.nodes_per_tag + 1;
  b.grid_height = (layout.rows - 1) * b.nodes_per_pitch + b.nodes_per_tag + 1;
  if (static_cast<long>(b.grid_width) * b.grid_height > 1000000)
    throw InputError("", "gap_mm",
                     "the board grid would have more than 10^6 points (spacing " +
                         significant_digits(b.spacing_mm, 10) + " mm)",
                     "use gap_mm = tag_mm");
  return b;
}

std::optional<GridIndex> Board::corner_grid_index(int tag_id, int k) const {
  if (k < 0 || k > 3)
    throw std::invalid_argument("Board::corner_grid_index: corner k must be 0..3, got " + std::to_string(k));
  if (!has_tag(tag_id)) return std::nullopt;
  const int index = tag_id - layout.first_id;
  const int r = index / layout.cols, c = index % layout.cols;
  GridIndex g{r * nodes_per_pitch, c * nodes_per_pitch};
  // AprilTag order for an upright tag: bottom-left, bottom-right, top-right, top-left (y down).
  if (k == 0 || k == 1) g.row += nodes_per_tag;
  if (k == 1 || k == 2) g.col += nodes_per_tag;
  return g;
}

std::optional<std::pair<int, int>> Board::tag_corner_at(GridIndex g) const {
  // A node coordinate n is the near edge of tag n / pitch (n % pitch == 0) or the far edge of tag
  // (n - nodes_per_tag) / pitch; both cannot hold since 0 < nodes_per_tag < nodes_per_pitch.
  auto resolve = [&](int n, int count, int& tag, bool& far) {
    if (n >= 0 && n % nodes_per_pitch == 0 && n / nodes_per_pitch < count) {
      tag = n / nodes_per_pitch, far = false;
      return true;
    }
    const int m = n - nodes_per_tag;
    if (m >= 0 && m % nodes_per_pitch == 0 && m / nodes_per_pitch < count) {
      tag = m / nodes_per_pitch, far = true;
      return true;
    }
    return false;
  };
  int ti = 0, tj = 0;
  bool bottom = false, right = false;
  if (!resolve(g.row, layout.rows, ti, bottom) || !resolve(g.col, layout.cols, tj, right))
    return std::nullopt;
  const int k = bottom ? (right ? 1 : 0) : (right ? 2 : 3);
  return std::make_pair(layout.first_id + ti * layout.cols + tj, k);
}

Eigen::Vector3d Board::point_mm(GridIndex g) const { return {g.col * spacing_mm, g.row * spacing_mm, 0.0}; }

std::vector<Eigen::Vector3d> Board::points_mm() const {
  std::vector<Eigen::Vector3d> p;
  p.reserve(static_cast<std::size_t>(num_points()));
  for (int i = 0; i < grid_height; ++i)
    for (int j = 0; j < grid_width; ++j) p.push_back(point_mm({i, j}));
  return p;
}

Eigen::Vector2d Board::tag_origin_mm(int tag_id) const {
  if (!has_tag(tag_id))
    throw std::invalid_argument("Board::tag_origin_mm: tag " + std::to_string(tag_id) +
                                " is not on the board");
  const int index = tag_id - layout.first_id;
  const double pitch = layout.tag_mm + layout.gap_mm;
  return {(index % layout.cols) * pitch, (index / layout.cols) * pitch};
}

double Board::margin_mm() const {
  const double cell = cell_mm();
  return std::max((cells_total - cells_at_border) / 2.0 * cell + cell, layout.gap_mm / 2);
}

std::string board_to_yaml(const Board& b) {
  YAML::Emitter e;
  e.SetDoublePrecision(12);
  e << YAML::BeginMap;
  e << YAML::Key << "schema" << YAML::Value << "clearfit.board/1";
  e << YAML::Key << "family" << YAML::Value << b.layout.family;
  e << YAML::Key << "rows" << YAML::Value << b.layout.rows;
  e << YAML::Key << "cols" << YAML::Value << b.layout.cols;
  e << YAML::Key << "tag_mm" << YAML::Value << b.layout.tag_mm;
  e << YAML::Key << "gap_mm" << YAML::Value << b.layout.gap_mm;
  e << YAML::Key << "first_id" << YAML::Value << b.layout.first_id;
  e << YAML::Key << "grid_width" << YAML::Value << b.grid_width;
  e << YAML::Key << "grid_height" << YAML::Value << b.grid_height;
  e << YAML::Key << "spacing_mm" << YAML::Value << b.spacing_mm;
  e << YAML::EndMap;
  return std::string(e.c_str()) + "\n";
}

void write_board(const Board& board, const std::filesystem::path& path) {
  if (board.num_tags() == 0) throw std::invalid_argument("write_board: empty board");
  write_file_atomically(path, board_to_yaml(board));
}

Board read_board(const std::filesystem::path& path) {
  const std::string file = path.string();
  if (!std::filesystem::is_regular_file(path))
    throw InputError(file, "", "board file not found",
                     "write one with `clearfit board ... --board-file FILE`");
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::Exception& e) {
    throw InputError(file, "line " + std::to_string(e.mark.line + 1), "not a valid YAML/JSON file: " + e.msg);
  }
  if (!root.IsMap())
    throw InputError(file, "",
                     "expected a map of keys (schema, family, rows, cols, tag_mm, gap_mm, first_id)");
  auto where = [&](const YAML::Node& n, const std::string& key) {
    return "key '" + key + "' (line " + std::to_string(n.Mark().line + 1) + ")";
  };
  static const std::set<std::string> known{"schema", "family",   "rows",       "cols",        "tag_mm",
                                           "gap_mm", "first_id", "grid_width", "grid_height", "spacing_mm"};
  for (const auto& kv : root) {
    const std::string key = yaml_key(kv.first, file);
    if (!known.count(key))
      throw InputError(
          file, where(kv.first, key), "unknown key",
          "known keys: schema family rows cols tag_mm gap_mm first_id grid_width grid_height spacing_mm");
  }
  auto get = [&]<typename T>(const std::string& key, T fallback, bool required) -> T {
    const YAML::Node n = root[key];
    if (!n) {
      if (required) throw InputError(file, "key '" + key + "'", "missing");
      return fallback;
    }
    try {
      return n.as<T>();
    } catch (const YAML::Exception&) {
      throw InputError(file, where(n, key),
                       std::string("wrong type: expected ") + (std::is_same_v<T, std::string> ? "text"
                                                               : std::is_integral_v<T>        ? "an integer"
                                                                                              : "a number"));
    }
  };
  const std::string schema = get.template operator()<std::string>("schema", "", true);
  if (schema != "clearfit.board/1")
    throw InputError(file, where(root["schema"], "schema"),
                     "expected 'clearfit.board/1', got '" + schema + "'");
  BoardLayout layout;
  layout.family = get.template operator()<std::string>("family", "tag36h11", false);
  layout.rows = get.template operator()<int>("rows", 0, true);
  layout.cols = get.template operator()<int>("cols", 0, true);
  layout.tag_mm = get.template operator()<double>("tag_mm", 0, true);
  layout.gap_mm = get.template operator()<double>("gap_mm", 0, true);
  layout.first_id = get.template operator()<int>("first_id", 0, false);
  Board b;
  try {
    b = make_board(layout);
  } catch (const InputError& e) {
    const YAML::Node n = root[e.element()];
    throw InputError(file, n ? where(n, e.element()) : e.element(), e.what());
  }
  auto check = [&](const char* key, double derived) {
    if (const YAML::Node n = root[key]) {
      const double v = get.template operator()<double>(key, 0, false);
      if (std::abs(v - derived) > 1e-9 * std::max(1.0, std::abs(derived)))
        throw InputError(file, where(n, key),
                         "says " + significant_digits(v, 10) + " but the layout gives " +
                             significant_digits(derived, 10) +
                             ": the file disagrees with its own layout (edited by hand?)",
                         "remove the key or fix the layout");
    }
  };
  check("grid_width", b.grid_width);
  check("grid_height", b.grid_height);
  check("spacing_mm", b.spacing_mm);
  return b;
}

std::vector<std::uint8_t> tag_cells(const Board& board, int tag_id) {
  if (!board.has_tag(tag_id))
    throw std::invalid_argument("tag_cells: tag " + std::to_string(tag_id) + " is not on the board");
  const detail::FamilyPtr family = detail::create_family(board.layout.family);
  if (!family) throw std::invalid_argument("tag_cells: unknown family " + board.layout.family);
  image_u8_t* im = apriltag_to_image(family.get(), tag_id);
  std::vector<std::uint8_t> cells(static_cast<std::size_t>(im->width) * im->height);
  for (int y = 0; y < im->height; ++y)
    for (int x = 0; x < im->width; ++x)
      cells[static_cast<std::size_t>(y) * im->width + x] = im->buf[y * im->stride + x] > 127;
  image_u8_destroy(im);
  return cells;
}

std::string board_svg(const Board& b) {
  if (b.num_tags() == 0) throw std::invalid_argument("board_svg: empty board");
  const double margin = b.margin_mm(), caption = 24.0;
  const double page_w = std::max(b.width_mm() + 2 * margin, 80.0),
               page_h = b.height_mm() + 2 * margin + caption;
  const double x0 = (page_w - b.width_mm()) / 2, y0 = margin;  // board origin on the page
  std::ostringstream s;
  s.precision(10);
  s << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
    << "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"" << page_w << "mm\" height=\""
    << page_h << "mm\" viewBox=\"0 0 " << page_w << ' ' << page_h << "\">\n"
    << "<!-- clearfit board (clearfit.board/1): " << describe(b) << "; units: mm -->\n"
    << "<rect x=\"0\" y=\"0\" width=\"" << page_w << "\" height=\"" << page_h << "\" fill=\"#ffffff\"/>\n"
    << "<g id=\"tags\" fill=\"#000000\" shape-rendering=\"crispEdges\">\n";
  const double cell = b.cell_mm();
  const int n = b.cells_total;
  const double border = (b.cells_total - b.cells_at_border) / 2.0 * cell;
  for (int id = b.layout.first_id; id < b.layout.first_id + b.num_tags(); ++id) {
    const std::vector<std::uint8_t> cells = tag_cells(b, id);
    const Eigen::Vector2d o = b.tag_origin_mm(id) + Eigen::Vector2d(x0 - border, y0 - border);
    s << "<g id=\"tag" << id << "\">";
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n;) {
        if (cells[static_cast<std::size_t>(r) * n + c]) {
          ++c;
          continue;
        }
        int e = c;
        while (e < n && !cells[static_cast<std::size_t>(r) * n + e]) ++e;
        s << "<rect x=\"" << o.x() + c * cell << "\" y=\"" << o.y() + r * cell << "\" width=\""
          << (e - c) * cell << "\" height=\"" << cell << "\"/>";
        c = e;
      }
    s << "</g>\n";
  }
  s << "</g>\n";
  // Scale bar with 10 mm ticks.
  double bar = 10;
  for (double len : {100.0, 50.0, 20.0})
    if (len <= page_w - 20) {
      bar = len;
      break;
    }
  const double bx = 10, by = y0 + b.height_mm() + margin + 6;
  s << "<g id=\"scale\" stroke=\"#000000\" stroke-width=\"0.2\" fill=\"none\">\n"
    << "<line x1=\"" << bx << "\" y1=\"" << by << "\" x2=\"" << bx + bar << "\" y2=\"" << by << "\"/>\n";
  for (double t = 0; t <= bar + 1e-9; t += (bar >= 20 ? 10 : 5))
    s << "<line x1=\"" << bx + t << "\" y1=\"" << by - 2 << "\" x2=\"" << bx + t << "\" y2=\"" << by
      << "\"/>\n";
  s << "</g>\n<g id=\"labels\" font-family=\"sans-serif\" font-size=\"2.5\" fill=\"#000000\">\n";
  for (double t = 0; t <= bar + 1e-9; t += (bar >= 20 ? 10 : 5))
    s << "<text x=\"" << bx + t << "\" y=\"" << by - 2.6 << "\" text-anchor=\"middle\">" << t << "</text>\n";
  s << "<text x=\"" << bx + bar + 3 << "\" y=\"" << by + 0.9 << "\">" << bar << " mm</text>\n"
    << "<text x=\"" << bx << "\" y=\"" << by + 6 << "\">" << describe(b) << "</text>\n"
    << "<text x=\"" << bx << "\" y=\"" << by + 10 << "\">Print at 100 % (no fit to page). Check: the bar is "
    << bar << " mm, each black square " << significant_digits(b.layout.tag_mm, 10) << " mm, square to square "
    << significant_digits(b.layout.tag_mm + b.layout.gap_mm, 10) << " mm.</text>\n</g>\n</svg>\n";
  return s.str();
}

std::string describe(const Board& b) {
  std::ostringstream s;
  s << b.layout.family << ", " << b.layout.rows << " x " << b.layout.cols << " tags of "
    << significant_digits(b.layout.tag_mm, 10) << " mm, gap " << significant_digits(b.layout.gap_mm, 10)
    << " mm, ids " << b.layout.first_id << ".." << b.layout.first_id + b.num_tags() - 1 << "; grid "
    << b.grid_width << " x " << b.grid_height << " points, spacing " << significant_digits(b.spacing_mm, 10)
    << " mm";
  return s.str();
}

}  // namespace clearfit
