#pragma once
// AprilTag calibration boards laid out for mrcal's board model.
//
// mrcal models a board as ONE uniform grid of grid_width x grid_height points,
// point (row i, col j) at (j * spacing_mm, i * spacing_mm, 0) in the board
// frame. A board of rows x cols tags puts the black-border square of tag
// (r, c) (tag_mm edge) at x0 = c * (tag_mm + gap_mm), y0 = r * (tag_mm + gap_mm);
// its four corners are grid points only when tag_mm and gap_mm are integer
// multiples of one spacing. The recommended layout is gap_mm == tag_mm: then
// spacing_mm = tag_mm and the grid is (2 cols) x (2 rows), every node a corner.
// Other commensurate layouts (e.g. gap = tag / 4) give a finer grid whose
// nodes between tags are never observed (always "missing", weight < 0).
//
// Board frame: x to the right along the columns, y down along the rows, z into
// the board (away from a viewer facing its printed side), origin at the top-left
// corner of tag (0, 0)'s black square. Tag ids: first_id + row * cols + col,
// row 0 at the top, every tag upright in print.
//
// Corner k of a tag follows the AprilTag library's detection order for an
// upright tag: 0 bottom-left, 1 bottom-right, 2 top-right, 3 top-left.
//
// Board file (`clearfit.board/1`, YAML; JSON is read too since it is YAML):
//   schema: clearfit.board/1
//   family: tag36h11
//   rows: 6
//   cols: 8
//   tag_mm: 20
//   gap_mm: 20
//   first_id: 0
//   # informative, recomputed on reading and checked when present:
//   grid_width: 16
//   grid_height: 12
//   spacing_mm: 20
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace clearfit {

/// What a user chooses (options of `clearfit board`, keys of a board file).
struct BoardLayout {
  std::string family = "tag36h11";  ///< AprilTag family name
  int rows = 0;                     ///< tags down
  int cols = 0;                     ///< tags across
  double tag_mm = 0;                ///< edge of a tag's black-border square, mm
  double gap_mm = 0;                ///< white gap between neighbouring black squares, mm
  int first_id = 0;                 ///< id of the top-left tag
};

/// A grid node: row (down) and column (across) in mrcal's board grid.
struct GridIndex {
  int row = 0;
  int col = 0;
  friend bool operator==(const GridIndex&, const GridIndex&) = default;
};

/// A validated board: the layout plus the derived grid. Build with make_board()
/// or read_board(); a default-constructed Board is empty (num_tags() == 0).
struct Board {
  BoardLayout layout;
  int grid_width = 0;       ///< grid nodes across (mrcal's object-width-n)
  int grid_height = 0;      ///< grid nodes down (object-height-n)
  double spacing_mm = 0;    ///< distance between neighbouring nodes, mm (object-spacing)
  int nodes_per_tag = 0;    ///< tag_mm / spacing_mm (1 for the recommended layout)
  int nodes_per_pitch = 0;  ///< (tag_mm + gap_mm) / spacing_mm (2 for the recommended layout)
  int cells_at_border = 0;  ///< the family's black-square width in bit cells (8 for tag36h11)
  int cells_total = 0;      ///< the family's full tag width in cells, white border included (10)
  int family_codes = 0;     ///< how many ids the family has

  int num_tags() const { return layout.rows * layout.cols; }
  int num_points() const { return grid_width * grid_height; }
  /// Edge of one bit cell of a tag, mm (tag_mm / cells_at_border).
  double cell_mm() const { return layout.tag_mm / cells_at_border; }
  /// True when `tag_id` is one of this board's tags.
  bool has_tag(int tag_id) const {
    return tag_id >= layout.first_id && tag_id < layout.first_id + num_tags();
  }
  /// Row-major index of a grid node: row * grid_width + col.
  int point_index(GridIndex g) const { return g.row * grid_width + g.col; }
  /// Grid node of corner k (0..3, AprilTag order) of tag `tag_id`; nullopt when
  /// the id is not on this board. std::invalid_argument for k outside 0..3.
  std::optional<GridIndex> corner_grid_index(int tag_id, int k) const;
  /// The (tag id, corner k) at a grid node, nullopt for nodes between tags.
  std::optional<std::pair<int, int>> tag_corner_at(GridIndex g) const;
  /// Position of a grid node in the board frame, mm: (col * spacing, row * spacing, 0).
  Eigen::Vector3d point_mm(GridIndex g) const;
  /// All grid nodes in row-major order (what mrcal's board model assumes), mm.
  std::vector<Eigen::Vector3d> points_mm() const;
  /// Top-left corner of the black square of tag `tag_id` in the board frame, mm.
  Eigen::Vector2d tag_origin_mm(int tag_id) const;
  /// Extent of the black squares: from (0,0) to (width_mm(), height_mm()).
  double width_mm() const { return (grid_width - 1) * spacing_mm; }
  double height_mm() const { return (grid_height - 1) * spacing_mm; }
  /// White margin a printed board needs around the outer black squares, mm:
  /// the tags' own white border plus one more cell (at least gap_mm / 2).
  double margin_mm() const;
};

/// Validates a layout and derives its grid. Throws InputError(file "",
/// element "rows"/"cols"/"tag_mm"/"gap_mm"/"family"/"first_id", problem, hint) when:
/// rows or cols < 1; tag_mm or gap_mm not finite and positive; the gap is
/// narrower than one bit cell (tags would touch: AprilTag needs the white
/// border); tag_mm and gap_mm not integer multiples of one spacing (ratio
/// p/q with q <= 16 found to 1e-6 relative), i.e. corners not on one grid;
/// an unknown family, or one whose detected square is not its outer black
/// border (reversed-border families such as tagStandard41h12); ids past the
/// family's last code.
Board make_board(const BoardLayout& layout);

/// Reads a board file (format above). Throws InputError naming the file and
/// the key (with its line) for a missing file, syntax error, unknown key,
/// wrong type, a schema other than clearfit.board/1, an invalid layout
/// (make_board's checks), or informative keys that disagree with the layout.
Board read_board(const std::filesystem::path& path);

/// Writes the board file (format above, informative keys included) atomically.
/// Throws InputError naming the path when it cannot be written.
void write_board(const Board& board, const std::filesystem::path& path);

/// The board file's text (what write_board writes).
std::string board_to_yaml(const Board& board);

/// The bit cells of tag `tag_id` as printed (the AprilTag library's
/// apriltag_to_image): cells_total x cells_total, row-major from the top-left
/// of the upright tag, 1 = white, 0 = black; the outer ring is the white
/// border, the next one the black border. std::invalid_argument for an id not on
/// the board.
std::vector<std::uint8_t> tag_cells(const Board& board, int tag_id);

/// A printable SVG of the board at exact physical size: the root element's
/// width and height are in mm and its viewBox is in mm (1 user unit = 1 mm),
/// so printing at 100 % (no "fit to page") gives the layout's sizes. White
/// page with the tags (black cells as rectangles, merged along rows), a
/// margin of margin_mm(), then a caption strip: a scale bar of 100, 50, 20 or
/// 10 mm (the longest that fits) with 10 mm ticks and labels, the layout text
/// and what to measure.
std::string board_svg(const Board& board);

/// One-line human description, e.g. "tag36h11, 6 x 8 tags of 20 mm, gap 20 mm,
/// ids 0..47; grid 16 x 12 points, spacing 20 mm".
std::string describe(const Board& board);

}  // namespace clearfit
