// Synthetic AprilTag board images through an mrcal lens model.
#include <clearfit/camera/render_board.hpp>

#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

namespace clearfit {

namespace {

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}
double unit(std::uint64_t h) { return static_cast<double>(h >> 11) * 0x1.0p-53; }

void require(bool ok, const std::string& field, double value, const std::string& rule) {
  if (!ok)
    throw std::invalid_argument("RenderOptions::" + field + " = " + std::to_string(value) + ": " + rule);
}

/// Colours of board-plane points: paper, tag cells, background.
struct BoardShader {
  const Board& board;
  const RenderOptions& opt;
  std::vector<std::vector<std::uint8_t>> cells;  // per tag, cells_total^2
  double pitch, cell, border, extent, paper_margin;

  BoardShader(const Board& b, const RenderOptions& o) : board(b), opt(o) {
    for (int t = 0; t < b.num_tags(); ++t) cells.push_back(tag_cells(b, b.layout.first_id + t));
    pitch = b.layout.tag_mm + b.layout.gap_mm;
    cell = b.cell_mm();
    border = (b.cells_total - b.cells_at_border) / 2.0 * cell;
    extent = b.cells_total * cell;
    paper_margin = o.paper_margin_mm >= 0 ? o.paper_margin_mm : b.margin_mm();
  }

  double shade(double x, double y) const {
    if (x < -paper_margin || y < -paper_margin || x > board.width_mm() + paper_margin ||
        y > board.height_mm() + paper_margin)
      return opt.background;
    const double cx = std::floor((x + border) / pitch), cy = std::floor((y + border) / pitch);
    if (cx < 0 || cy < 0 || cx >= board.layout.cols || cy >= board.layout.rows) return opt.white;
    const double lx = x + border - cx * pitch, ly = y + border - cy * pitch;
    if (lx >= extent || ly >= extent) return opt.white;
    const int n = board.cells_total;
    const int i = std::min(n - 1, static_cast<int>(lx / cell)),
              j = std::min(n - 1, static_cast<int>(ly / cell));
    const auto& c = cells[static_cast<std::size_t>(cy) * board.layout.cols + static_cast<std::size_t>(cx)];
    return c[static_cast<std::size_t>(j) * n + i] ? opt.white : opt.black;
  }
};

}  // namespace

void RenderOptions::validate() const {
  require(supersample >= 1 && supersample <= 16, "supersample", supersample, "must be 1..16");
  for (auto [name, v] : {std::pair{"black", black}, {"white", white}, {"background", background}})
    require(std::isfinite(v) && v >= 0 && v <= 255, name, v, "must be a grey level in 0..255");
  require(std::isfinite(paper_margin_mm), "paper_margin_mm", paper_margin_mm, "must be finite");
  require(std::isfinite(exposure) && exposure > 0, "exposure", exposure, "must be > 0");
  require(std::isfinite(blur_sigma_px) && blur_sigma_px >= 0, "blur_sigma_px", blur_sigma_px, "must be >= 0");
  require(std::isfinite(noise_sigma) && noise_sigma >= 0, "noise_sigma", noise_sigma, "must be >= 0");
}

cv::Mat render_board(const Board& board, const CameraModel& camera, const Rigid3& cam_from_board,
                     const RenderOptions& options, const RayGrid* rays) {
  options.validate();
  if (board.num_tags() == 0) throw std::invalid_argument("render_board: empty board");
  RayGrid own;
  if (rays) {
    if (rays->stride != 1 || rays->width != camera.width || rays->height != camera.height ||
        rays->intrinsics_hash != camera.intrinsics_hash())
      throw std::invalid_argument(
          "render_board: the ray grid is not unproject_image(camera, 1) of this camera");
  } else {
    own = unproject_image(camera, 1);
    rays = &own;
  }
  const int W = camera.width, H = camera.height, n = options.supersample;
  const BoardShader shader(board, options);
  const Rigid3 board_from_cam = cam_from_board.inverse();
  const Eigen::Vector3d origin = board_from_cam.translation;  // the camera centre, board frame
  const bool front = origin.z() < 0;                          // board z points away from its printed side

  // Board-plane point (mm) seen by every pixel centre; NaN where the ray misses
  // the front of the board. Sample points in between are interpolated
  // bilinearly (the perspective map is smooth: its error over one pixel is far
  // below 1e-3 px for boards farther than a few focal lengths' worth of pixels).
  std::vector<Eigen::Vector2d> on_board(static_cast<std::size_t>(W) * H, Eigen::Vector2d(NAN, NAN));
  tbb::parallel_for(0, H, [&](int y) {
    for (int x = 0; x < W; ++x) {
      const Vec3& d = rays->at(x, y);
      if (!front || !d.allFinite()) continue;
      const Eigen::Vector3d db = board_from_cam.apply_direction(d);
      if (db.z() <= 0) continue;
      const double t = -origin.z() / db.z();
      on_board[static_cast<std::size_t>(y) * W + x] = {origin.x() + t * db.x(), origin.y() + t * db.y()};
    }
  });
  auto board_at = [&](double px, double py) -> Eigen::Vector2d {
    const int i0 = std::clamp(static_cast<int>(std::floor(px)), 0, std::max(0, W - 2));
    const int j0 = std::clamp(static_cast<int>(std::floor(py)), 0, std::max(0, H - 2));
    const int i1 = std::min(i0 + 1, W - 1), j1 = std::min(j0 + 1, H - 1);
    const double fx = px - i0, fy = py - j0;
    auto at = [&](int i, int j) -> const Eigen::Vector2d& {
      return on_board[static_cast<std::size_t>(j) * W + i];
    };
    return (1 - fy) * ((1 - fx) * at(i0, j0) + fx * at(i1, j0)) +
           fy * ((1 - fx) * at(i0, j1) + fx * at(i1, j1));
  };
  auto shade = [&](const Eigen::Vector2d& b) {
    return b.allFinite() ? shader.shade(b.x(), b.y()) : options.background;
  };
  // A pixel whose four corners see one colour and whose footprint is under half
  // a bit cell is uniform: no supersampling needed.
  const double half_cell_mm = 0.5 * board.cell_mm();

  cv::Mat img(H, W, CV_32F);
  tbb::parallel_for(0, H, [&](int y) {
    float* row = img.ptr<float>(y);
    for (int x = 0; x < W; ++x) {
      const Eigen::Vector2d c00 = board_at(x - 0.5, y - 0.5), c10 = board_at(x + 0.5, y - 0.5),
                            c01 = board_at(x - 0.5, y + 0.5), c11 = board_at(x + 0.5, y + 0.5);
      const double v00 = shade(c00);
      const bool small = c00.allFinite() && c11.allFinite() && c10.allFinite() && c01.allFinite() &&
                         (c11 - c00).norm() < half_cell_mm && (c10 - c01).norm() < half_cell_mm;
      if (small && v00 == shade(c10) && v00 == shade(c01) && v00 == shade(c11)) {
        row[x] = static_cast<float>(v00);
        continue;
      }
      double sum = 0;
      for (int sy = 0; sy < n; ++sy)
        for (int sx = 0; sx < n; ++sx) {
          const std::uint64_t h = splitmix64((static_cast<std::uint64_t>(y) * W + x) * 256 + sy * 16 + sx);
          const double px = x - 0.5 + (sx + unit(h)) / n, py = y - 0.5 + (sy + unit(splitmix64(h))) / n;
          sum += shade(board_at(px, py));
        }
      row[x] = static_cast<float>(sum / (n * n));
    }
  });
  if (options.blur_sigma_px > 0)
    cv::GaussianBlur(img, img, cv::Size(0, 0), options.blur_sigma_px, 0, cv::BORDER_REPLICATE);
  img *= options.exposure;
  if (options.noise_sigma > 0) {
    std::mt19937_64 rng(options.seed);
    std::normal_distribution<float> noise(0.0f, static_cast<float>(options.noise_sigma));
    for (int y = 0; y < H; ++y) {
      float* row = img.ptr<float>(y);
      for (int x = 0; x < W; ++x) row[x] += noise(rng);
    }
  }
  cv::Mat out;
  img.convertTo(out, CV_8U);  // rounds and saturates to 0..255
  return out;
}

std::vector<Eigen::Vector3d> true_corners(const Board& board, const CameraModel& camera,
                                          const Rigid3& cam_from_board, double margin_px) {
  std::vector<Vec3> pts;
  for (const auto& p : board.points_mm()) pts.push_back(cam_from_board.apply(p));
  const std::vector<Vec2> px = camera.project(pts);
  std::vector<Eigen::Vector3d> out(pts.size(), Eigen::Vector3d(-1, -1, -1));
  for (int i = 0; i < board.grid_height; ++i)
    for (int j = 0; j < board.grid_width; ++j) {
      const int k = board.point_index({i, j});
      const Vec2& q = px[k];
      const bool inside = q.allFinite() && pts[k].z() > 0 && q.x() >= -0.5 + margin_px &&
                          q.y() >= -0.5 + margin_px && q.x() <= camera.width - 0.5 - margin_px &&
                          q.y() <= camera.height - 0.5 - margin_px;
      if (inside && board.tag_corner_at({i, j})) out[k] = {q.x(), q.y(), 1.0};
    }
  return out;
}

}  // namespace clearfit
