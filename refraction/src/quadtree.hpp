#pragma once
// Stage 4, grid and adaptive modes: a quadtree over pixel cells with up to
// nine nodes each (corners, edge midpoints, centre), all traced exactly; the
// interior is filled by tensor-product quadratic (Lagrange) interpolation of
// the nodes. Eight check pixels (the quadrants' centres and one drawn pixel
// per quadrant) are traced too; adaptive splits the cell into its quadrants
// (whose corners are nodes already) unless the interpolation is within half
// the tolerance at all eight and the parent's nodes and checks were all valid
// with an error of at most kTrustedParent tolerances (a cell beside a
// boundary, a discontinuity or a fold is not accepted on its own checks
// alone); with flat normals every node and check must also have entered the
// part through one face (the map jumps at facet edges). Each level's
// nodes and checks are traced in one batch. Small cells that a validity
// boundary crosses go to the boundary resolver instead of being split.
//
//   quadtree.cpp           the levels: trace nodes and checks, decide, split, fill
//   quadtree_fill.cpp      the interpolant and the fills of accepted cells
//   boundary_resolver.cpp  the small cells a validity boundary crosses
#include "chart_locator.hpp"
#include "map_stages.hpp"

#include <array>
#include <optional>
#include <vector>

namespace clearfit::refraction_detail {

constexpr double kUnknownErr = 1e300;  // a cell's error when its nodes and checks were not all valid
constexpr double kTopLevel = -1;       // the parent error of the first level's cells
struct Cell {
  int x0, y0, x1, y1;             // corner pixels (inclusive)
  double parent_err = kTopLevel;  // the parent's largest check error, mm, or kUnknownErr
};
// Check pixels per cell, at most: the quadrants' centres and one pixel drawn
// in each quadrant (see checks_of). The four centres alone missed the ripple
// that facets leave in the map on regularly tessellated parts (p99 1.4 µm
// at 1 µm on a 6.7k-triangle shell); two (one diagonal) missed errors like
// x³ − y³, which vanish on it.
constexpr int kMaxChecks = 8;
// adaptive accepts a cell when its checks are within this fraction of the
// tolerance: the map is only piecewise smooth (kinks along the images of mesh
// edges, where interpolated normals and facets meet), so the error between the
// checks reaches about twice theirs. Without a chart the interpolated points
// lie on a smooth surface through the nodes, off the flat facets the exact
// points lie on by up to the facets' sag (|dn|·edge/8); the drawn checks
// see it where the centres alone, at one place of a regular tessellation,
// did not (p99 1.23 µm before them). Measured on the random freeform family
// (tests/refraction/map_tolerance_test.cpp, 320x240 and 640x480, 1 µm): with
// a chart p99 0.36-0.64 µm, max 0.56-2.27 µm; without, p99 0.11-0.84 µm, max
// 0.65-2.53 µm.
constexpr double kAcceptFraction = 0.5;
// adaptive trusts a cell's checks only when its parent's error was at most
// this many tolerances: a smooth map's interpolation error falls 2-8x per
// split (linear beside kinks, cubic elsewhere), so a parent far above it has a
// jump or a fold between two valid branches inside (seen: 1.3 mm on a random
// shell, seed 58, whose child's checks all missed it).
constexpr double kTrustedParent = 16;
// Cells up to this size (pixels) that a validity boundary crosses go to the
// boundary resolver instead of being split further.
constexpr int kResolveCell = 8;

// What `traced` holds per pixel while the quadtree runs.
enum TraceState : char {
  kUntouched = 0,
  kExact = 1,     // traced
  kFilled = 2,    // interpolated, or reset as uniformly invalid
  kRelocate = 3,  // the chart location of its interpolation failed: to be traced
  kPending = 4,   // in a boundary cell, status guessed from the nearest node
  kQueued = 5,    // listed for the current trace
};

class Quadtree {
 public:
  explicit Quadtree(const MapRun& run);
  /// Resets the pixels outside the bound and fills those inside.
  void run();

 private:
  // ---- the interpolant (quadtree_fill.cpp)
  struct Interp {
    Vec3 point;
    int face;
    std::array<double, 3> bary;
    Vec2 uv;
  };
  struct Nodes {
    int n = 0;
    std::uint32_t pixel[9];
    int ax[3], ay[3], nx = 0, ny = 0;
  };
  // A cell prepared for the fill, written row by row across all cells of a
  // level (long runs along the rows write at about twice the memory bandwidth
  // of cell by cell). Gives interpolate()'s result up to rounding.
  struct DirectFill {
    // Per node's face: corner 0 and the two vectors whose dot products
    // with (point - corner 0) give the barycentric weights of corners 1, 2.
    struct Frame {
      Vec3 a, g1, g2;
      int face;
    };
    // skin point (with a chart: chart u, v, 0), incidence, contact, transmittance
    using Val = Eigen::Matrix<double, 6, 1>;
    Nodes q;
    int x0, y0, xe, ye;
    std::array<Frame, 9> frame;
    std::array<Val, 9> node_val;
    double wx0[3][3];      // x weights at x0, x0 + 1, x0 + 2
    int ix_from[3], ix_n;  // heaviest node column: column ix_of[k] from x0 + ix_from[k] on
    int ix_of[3];
  };
  std::uint32_t idx(int x, int y) const { return static_cast<std::uint32_t>(map_.index(x, y)); }
  /// Last column and row a cell fills (its right and bottom edges belong to
  /// the next cell unless they are the bound's).
  int x_end(const Cell& c) const { return c.x1 == box_.x1 ? c.x1 : c.x1 - 1; }
  int y_end(const Cell& c) const { return c.y1 == box_.y1 ? c.y1 : c.y1 - 1; }
  Nodes nodes_of(const Cell& c) const;
  static std::array<double, 9> weights(const Nodes& q, int x, int y);
  /// With a chart, chart coordinates are interpolated (smooth: no surface
  /// sag) and put back on the mesh by point location, so the point lies on
  /// the surface. Without one: the skin points themselves, with the face of
  /// the heaviest node. nullopt: the location fell outside the chart. `hint`:
  /// a face to try first (the previous pixel's).
  std::optional<Interp> interpolate(const Nodes& q, const std::array<double, 9>& w, int hint = -1) const;
  void prepare_direct(const Cell& c, DirectFill& f) const;
  long long fill_direct_row(const DirectFill& f, int y);
  void fill_invalid_row(int x0, int xe, int y, PixelStatus why);

  // ---- the levels (quadtree.cpp)
  /// Exact trace of the listed pixels that are not traced yet.
  void trace_pixels(const std::vector<std::uint32_t>& pixels_in);
  static bool done(const Cell& c) { return c.x1 - c.x0 <= 2 && c.y1 - c.y0 <= 2; }  // every pixel is a node
  struct Checks {
    int n = 0;
    int x[kMaxChecks], y[kMaxChecks];
    std::uint32_t pixel[kMaxChecks];
  };
  Checks checks_of(const Cell& c) const;
  bool corners_differ(const Cell& c) const;
  enum Decision : char { skip = 0, accept_valid = 1, accept_invalid = 2, split = 3, to_resolver = 4 };
  void decide(const std::vector<Cell>& cells, std::vector<char>& decision, std::vector<double>& cell_err) const;
  void fill_accepted(const std::vector<Cell>& cells, const std::vector<char>& decision);
  void fill_accepted_by_rows(const std::vector<Cell>& cells, const std::vector<char>& decision,
                             std::vector<std::size_t>& accepted);

  // ---- the boundary resolver (boundary_resolver.cpp)
  void resolve_boundary(const std::vector<Cell>& cells);
  std::vector<std::vector<std::uint32_t>> guess_boundary_cells(const std::vector<Cell>& cells);
  bool borders_other(std::uint32_t p) const;
  void trace_boundary(std::vector<std::uint32_t>& pending);
  /// The pending valid pixels of one cell from a least-squares quadratic;
  /// returns those it could not fill.
  std::vector<std::uint32_t> fit_behind(const Cell& c, const std::vector<std::uint32_t>& pixels, double& fit_err,
                                        long long& fitted);
  std::uint32_t nearest_known(int x, int y, const std::vector<std::uint32_t>& known) const;

  const MapRun& run_;
  const Mesh& mesh_;
  RefractionMap& map_;
  MapStats& st_;
  const PixelBox box_;
  const int W_;
  const bool adaptive_;
  const double tol_mm_;
  const double accept_mm_;  // kAcceptFraction * tol_mm_
  const std::vector<int>& component_;
  std::vector<char> traced_;
  // Flat normals only: the entry face of every traced pixel. The map jumps
  // where the entry face changes (each facet refracts with its own normal), so
  // a cell is accepted only if its nodes and checks all entered through one face.
  const bool flat_;
  std::vector<std::int32_t> entry_face_;
  std::optional<ChartLocator> locator_;
  double worst_ = 0;
};

}  // namespace clearfit::refraction_detail
