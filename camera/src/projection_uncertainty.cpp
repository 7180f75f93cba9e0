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

constexpr const char* kCells = "clearfit_uncertainty_cells";
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

}  // namespace

double ProjectionUncertainty::at(const Vec2& pixel, int width, int height) const {
  // Cell centre c of n over a side of W pixels: (c + 0.5)·W/n − 0.5; invert and clamp.
  const double fx = std::clamp((pixel.x() + 0.5) * cells_x / width - 0.5, 0.0, cells_x - 1.0);
  const double fy = std::clamp((pixel.y() + 0.5) * cells_y / height - 0.5, 0.0, cells_y - 1.0);
  const int x0 = std::min(static_cast<int>(fx), cells_x - 1), y0 = std::min(static_cast<int>(fy), cells_y - 1);
  const int x1 = std::min(x0 + 1, cells_x - 1), y1 = std::min(y0 + 1, cells_y - 1);
  const double tx = fx - x0, ty = fy - y0;
  auto v = [&](int x, int y) { return px[static_cast<std::size_t>(y) * cells_x + x]; };
  return (1 - ty) * ((1 - tx) * v(x0, y0) + tx * v(x1, y0)) + ty * ((1 - tx) * v(x0, y1) + tx * v(x1, y1));
}

double ProjectionUncertainty::largest() const { return px.empty() ? 0.0 : *std::max_element(px.begin(), px.end()); }

std::optional<ProjectionUncertainty> read_projection_uncertainty(const std::filesystem::path& cameramodel) {
  const std::string file = cameramodel.string();
  std::ifstream in(cameramodel, std::ios::binary);
  if (!in) throw InputError(file, "", "cannot be read");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  const std::size_t cells_at = find_key(text, kCells), distance_at = find_key(text, kDistance), px_at = find_key(text, kPixels);
  const int found = (cells_at != std::string::npos) + (distance_at != std::string::npos) + (px_at != std::string::npos);
  if (found == 0) return std::nullopt;
  if (found < 3)
    throw InputError(file, "key '" + std::string(cells_at == std::string::npos ? kCells : distance_at == std::string::npos ? kDistance : kPixels) + "'",
                     "is missing: the projection uncertainty needs all three clearfit_uncertainty_* keys",
                     "write the model with `clearfit calibrate`, or remove the other keys");
  const std::vector<double> cells = numbers(file, text, cells_at, kCells), distance = numbers(file, text, distance_at, kDistance);
  ProjectionUncertainty u;
  u.px = numbers(file, text, px_at, kPixels);
  if (cells.size() != 2 || cells[0] < 1 || cells[1] < 1 || cells[0] != std::floor(cells[0]) || cells[1] != std::floor(cells[1]) ||
      cells[0] * cells[1] > 1e6)
    throw InputError(file, where(text, cells_at, kCells), "expected two whole numbers of cells >= 1 (x, y)");
  u.cells_x = static_cast<int>(cells[0]), u.cells_y = static_cast<int>(cells[1]);
  if (distance.size() != 1 || !(distance[0] > 0)) throw InputError(file, where(text, distance_at, kDistance), "expected one distance > 0 mm");
  u.distance_mm = distance[0];
  if (u.px.size() != static_cast<std::size_t>(u.cells_x) * u.cells_y)
    throw InputError(file, where(text, px_at, kPixels),
                     "holds " + std::to_string(u.px.size()) + " values; the cells (" + std::to_string(u.cells_x) + " x " +
                         std::to_string(u.cells_y) + ") need " + std::to_string(u.cells_x * u.cells_y));
  if (std::any_of(u.px.begin(), u.px.end(), [](double v) { return v < 0; }))
    throw InputError(file, where(text, px_at, kPixels), "holds a negative sigma", "sigmas in pixels are >= 0");
  return u;
}

void write_cameramodel(const CameraModel& model, const ProjectionUncertainty& u, const std::filesystem::path& path) {
  if (u.cells_x < 1 || u.cells_y < 1 || u.px.size() != static_cast<std::size_t>(u.cells_x) * u.cells_y || !(u.distance_mm > 0) ||
      std::any_of(u.px.begin(), u.px.end(), [](double v) { return !(v >= 0) || !std::isfinite(v); }))
    throw std::invalid_argument("write_cameramodel(" + path.string() + "): the projection uncertainty's cells, distance or values are invalid");
  std::string text = cameramodel_text(model, path);
  std::string keys = "\n    # clearfit: projection uncertainty (mrcal's method), 1-sigma px in the worst direction at the centres\n"
                     "    # of a grid of cells over the imager, row-major, for points at the distance given\n";
  keys += "    '" + std::string(kCells) + "': [ " + std::to_string(u.cells_x) + ", " + std::to_string(u.cells_y) + ", ],\n";
  keys += "    '" + std::string(kDistance) + "': " + significant_digits(u.distance_mm, 17) + ",\n";
  keys += "    '" + std::string(kPixels) + "': [ ";
  for (double v : u.px) keys += significant_digits(v, 17) + ", ";
  keys += "],\n";
  text.insert(text.rfind('}'), keys);
  write_file_atomically(path, text);
}

}  // namespace clearfit
