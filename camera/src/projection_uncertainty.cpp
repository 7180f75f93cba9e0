// The projection uncertainty's keys in a .cameramodel (projection_uncertainty.hpp).
#include <clearfit/atomic_file.hpp>
#include <clearfit/camera/projection_uncertainty.hpp>
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

namespace clearfit {
namespace {

constexpr const char* kNodes = "clearfit_uncertainty_nodes";
constexpr const char* kCells = "clearfit_uncertainty_cells";  // models written before the nodes
constexpr const char* kDistance = "clearfit_uncertainty_distance_mm";
constexpr const char* kPixels = "clearfit_uncertainty_px";

/// Where 'key' (or "key") stands in the text, outside comments; npos when it does not.
std::size_t find_key(const std::string& text, const std::string& key) {
  for (const char quote : {'\'', '"'}) {
    const std::string needle = quote + key + quote;
    for (std::size_t at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1)) {
      const std::size_t line = text.rfind('\n', at);
      const std::size_t hash = text.find('#', line == std::string::npos ? 0 : line);
      if (hash == std::string::npos || hash > at) return at;
    }
  }
  return std::string::npos;
}

std::string where(const std::string& text, std::size_t at, const std::string& key) {
  return "line " + std::to_string(1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n')) + ", key '" + key + "'";
}

/// The numbers of the key's value: a list [a, b, ...] or one number.
std::vector<double> numbers(const std::string& file, const std::string& text, std::size_t at, const std::string& key) {
  std::size_t i = text.find(':', at);
  if (i == std::string::npos) throw InputError(file, where(text, at, key), "has no value");
  ++i;
  while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
  const bool list = i < text.size() && text[i] == '[';
  const std::size_t end = list ? text.find(']', i) : text.find_first_of(",}\n", i);
  if (end == std::string::npos) throw InputError(file, where(text, at, key), "has no end");
  std::string body = text.substr(list ? i + 1 : i, end - (list ? i + 1 : i));
  std::replace(body.begin(), body.end(), ',', ' ');
  std::istringstream in(body);
  std::vector<double> out;
  for (std::string token; in >> token;) {
    double v = 0;
    const auto [p, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
    if (ec != std::errc() || p != token.data() + token.size() || !std::isfinite(v))
      throw InputError(file, where(text, at, key), "expected finite numbers, found '" + token + "'");
    out.push_back(v);
  }
  return out;
}

/// Pixel coordinate `p` along a side of `size` pixels as a fractional index into n grid points, clamped to them.
double grid_index(ProjectionUncertainty::Layout layout, double p, int n, int size) {
  const double f = layout == ProjectionUncertainty::Layout::nodes ? (size > 1 ? p * (n - 1) / (size - 1) : 0.0)
                                                                  : (p + 0.5) * n / size - 0.5;  // cell c's centre: (c + 0.5)·W/n − 0.5
  return std::clamp(f, 0.0, n - 1.0);
}

/// Pixel coordinate of grid point i of n along a side of `size` pixels (grid_index's inverse).
double grid_pixel(ProjectionUncertainty::Layout layout, int i, int n, int size) {
  return layout == ProjectionUncertainty::Layout::nodes ? (n > 1 ? double(i) * (size - 1) / (n - 1) : 0.5 * (size - 1))
                                                        : (i + 0.5) * size / n - 0.5;
}

}  // namespace

std::vector<Vec2> uncertainty_sample_pixels(ProjectionUncertainty::Layout layout, int nx, int ny, int width, int height) {
  std::vector<Vec2> q;
  q.reserve(static_cast<std::size_t>(std::max(nx, 0)) * std::max(ny, 0));
  for (int iy = 0; iy < ny; ++iy)
    for (int ix = 0; ix < nx; ++ix) q.emplace_back(grid_pixel(layout, ix, nx, width), grid_pixel(layout, iy, ny, height));
  return q;
}

double ProjectionUncertainty::at(const Vec2& pixel, int width, int height) const {
  const double fx = grid_index(layout, pixel.x(), nx, width), fy = grid_index(layout, pixel.y(), ny, height);
  const int x0 = std::min(static_cast<int>(fx), nx - 1), y0 = std::min(static_cast<int>(fy), ny - 1);
  const int x1 = std::min(x0 + 1, nx - 1), y1 = std::min(y0 + 1, ny - 1);
  const double tx = fx - x0, ty = fy - y0;
  auto v = [&](int x, int y) { return px[static_cast<std::size_t>(y) * nx + x]; };
  return (1 - ty) * ((1 - tx) * v(x0, y0) + tx * v(x1, y0)) + ty * ((1 - tx) * v(x0, y1) + tx * v(x1, y1));
}

double ProjectionUncertainty::largest() const { return px.empty() ? 0.0 : *std::max_element(px.begin(), px.end()); }

bool ProjectionUncertainty::valid() const {
  const int least = layout == Layout::nodes ? 2 : 1;
  return nx >= least && ny >= least && px.size() == static_cast<std::size_t>(nx) * ny && distance_mm > 0 && std::isfinite(distance_mm) &&
         std::all_of(px.begin(), px.end(), [](double v) { return v >= 0 && std::isfinite(v); });
}

std::optional<ProjectionUncertainty> read_projection_uncertainty(const std::filesystem::path& cameramodel) {
  const std::string file = cameramodel.string();
  std::ifstream in(cameramodel, std::ios::binary);
  if (!in) throw InputError(file, "", "cannot be read");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  const std::size_t nodes_at = find_key(text, kNodes), cells_at = find_key(text, kCells);
  const std::size_t distance_at = find_key(text, kDistance), px_at = find_key(text, kPixels);
  if (nodes_at != std::string::npos && cells_at != std::string::npos)
    throw InputError(file, where(text, std::max(nodes_at, cells_at), nodes_at > cells_at ? kNodes : kCells),
                     "is given with '" + std::string(nodes_at > cells_at ? kCells : kNodes) + "': the projection uncertainty has one grid",
                     "keep the key `clearfit calibrate` wrote and remove the other");
  const bool nodes = nodes_at != std::string::npos;
  const std::size_t grid_at = nodes ? nodes_at : cells_at;
  const std::string grid_key = nodes ? kNodes : kCells, points = nodes ? "nodes" : "cells";
  const int found = (grid_at != std::string::npos) + (distance_at != std::string::npos) + (px_at != std::string::npos);
  if (found == 0) return std::nullopt;
  if (found < 3)
    throw InputError(file,
                     grid_at == std::string::npos ? "key '" + std::string(kNodes) + "' (or the older '" + kCells + "')"
                                                  : "key '" + std::string(distance_at == std::string::npos ? kDistance : kPixels) + "'",
                     "is missing: the projection uncertainty needs all three clearfit_uncertainty_* keys",
                     "write the model with `clearfit calibrate`, or remove the other keys");
  const std::vector<double> grid = numbers(file, text, grid_at, grid_key), distance = numbers(file, text, distance_at, kDistance);
  ProjectionUncertainty u;
  u.layout = nodes ? ProjectionUncertainty::Layout::nodes : ProjectionUncertainty::Layout::cells;
  u.px = numbers(file, text, px_at, kPixels);
  const double least = nodes ? 2 : 1;
  if (grid.size() != 2 || grid[0] < least || grid[1] < least || grid[0] != std::floor(grid[0]) || grid[1] != std::floor(grid[1]) ||
      grid[0] * grid[1] > 1e6)
    throw InputError(file, where(text, grid_at, grid_key), "expected two whole numbers of " + points + " >= " + std::to_string(int(least)) + " (x, y)");
  u.nx = static_cast<int>(grid[0]), u.ny = static_cast<int>(grid[1]);
  if (distance.size() != 1 || !(distance[0] > 0)) throw InputError(file, where(text, distance_at, kDistance), "expected one distance > 0 mm");
  u.distance_mm = distance[0];
  if (u.px.size() != static_cast<std::size_t>(u.nx) * u.ny)
    throw InputError(file, where(text, px_at, kPixels),
                     "holds " + std::to_string(u.px.size()) + " values; the " + points + " (" + std::to_string(u.nx) + " x " +
                         std::to_string(u.ny) + ") need " + std::to_string(u.nx * u.ny));
  if (std::any_of(u.px.begin(), u.px.end(), [](double v) { return v < 0; }))
    throw InputError(file, where(text, px_at, kPixels), "holds a negative sigma", "sigmas in pixels are >= 0");
  return u;
}

void write_cameramodel(const CameraModel& model, const ProjectionUncertainty& u, const std::filesystem::path& path) {
  if (!u.valid())
    throw std::invalid_argument("write_cameramodel(" + path.string() + "): the projection uncertainty's grid, distance or values are invalid");
  const bool nodes = u.layout == ProjectionUncertainty::Layout::nodes;
  std::string text = cameramodel_text(model, path);
  std::string keys = "\n    # clearfit: projection uncertainty (mrcal's method), 1-sigma px in the worst direction, row-major, for\n";
  keys += nodes ? "    # points at the distance given, at the nodes of a grid spanning the imager: node i of n at i (W-1)/(n-1)\n"
                : "    # points at the distance given, at the centres of a grid of cells over the imager\n";
  keys += "    '" + std::string(nodes ? kNodes : kCells) + "': [ " + std::to_string(u.nx) + ", " + std::to_string(u.ny) + ", ],\n";
  keys += "    '" + std::string(kDistance) + "': " + significant_digits(u.distance_mm, 17) + ",\n";
  keys += "    '" + std::string(kPixels) + "': [ ";
  for (double v : u.px) keys += significant_digits(v, 17) + ", ";
  keys += "],\n";
  text.insert(text.rfind('}'), keys);
  write_file_atomically(path, text);
}

}  // namespace clearfit
