// Calibration inputs: mrcal's corners.vnl (read and write) and OpenCV
// calibration files converted to mrcal models.
#include <clearfit/atomic_file.hpp>
#include <clearfit/camera/calibrate.hpp>
#include <clearfit/error.hpp>

#include <opencv2/core.hpp>

#include <charconv>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <map>
#include <sstream>

namespace clearfit {
namespace {

std::optional<double> parse_number(const std::string& s) {
  double v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

}  // namespace

std::vector<BoardObservation> read_corners_vnl(const std::filesystem::path& path, const CalibrationGrid& grid,
                                               int width, int height, bool with_weights) {
  grid.validate();
  std::ifstream in(path);
  if (!in) throw InputError(path.string(), "", "cannot be opened", "check the path");
  const std::size_t per_view = static_cast<std::size_t>(grid.width) * grid.height;
  std::vector<BoardObservation> views;
  std::map<std::string, std::size_t> index;
  std::vector<int> start_line;
  std::string line;
  int line_no = 0;
  auto where = [&] { return "line " + std::to_string(line_no); };
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos) continue;
    if (line[first] == '#') {
      if (line_no == 1 && line.find("weight") != std::string::npos) with_weights = true;
      continue;
    }
    std::istringstream s(line);
    std::vector<std::string> tok;
    for (std::string t; s >> t;) tok.push_back(t);
    if (tok.size() != 3 && tok.size() != 4)
      throw InputError(
          path.string(), where(),
          "expected 'filename x y level' (3 or 4 columns), found " + std::to_string(tok.size()) + " columns");
    auto [it, added] = index.try_emplace(tok[0], views.size());
    if (added) {
      views.push_back({tok[0], width, height, {}, {}, 0});
      start_line.push_back(line_no);
    } else if (it->second + 1 != views.size()) {
      throw InputError(path.string(), where(), "rows of image '" + tok[0] + "' are not contiguous",
                       "keep each image's rows together");
    }
    BoardObservation& v = views[it->second];
    if (tok[1] == "-" || tok[2] == "-") {
      v.corners.emplace_back(-1, -1, -1);
      continue;
    }
    const auto x = parse_number(tok[1]), y = parse_number(tok[2]);
    if (!x || !y) throw InputError(path.string(), where(), "x and y must be numbers or '-'");
    double weight = 1;
    if (tok.size() == 4 && tok[3] != "-") {
      const auto c = parse_number(tok[3]);
      if (!c) throw InputError(path.string(), where(), "the last column must be a number or '-'");
      weight = with_weights ? *c : (*c < 0 ? -1.0 : std::pow(0.5, *c));
    } else if (tok.size() == 4) {
      weight = -1;
    }
    v.corners.emplace_back(*x, *y, weight);
  }
  for (std::size_t k = 0; k < views.size(); ++k) {
    auto& v = views[k];
    const bool none = v.corners.size() == 1 && v.corners[0].z() < 0;
    if (none)
      v.corners.assign(per_view, Eigen::Vector3d(-1, -1, -1));
    else if (v.corners.size() != per_view)
      throw InputError(path.string(), "line " + std::to_string(start_line[k]),
                       "image '" + v.image + "' has " + std::to_string(v.corners.size()) + " rows; a " +
                           std::to_string(grid.width) + " x " + std::to_string(grid.height) +
                           " board needs " + std::to_string(per_view) +
                           " (or one 'filename - - -' row for no detection)",
                       "check --grid / the board file against the board the corners came from");
  }
  if (views.empty())
    throw InputError(path.string(), "", "holds no corner rows", "detect the board corners first");
  return views;
}

void write_corners_levels_vnl(const std::vector<BoardObservation>& views, const std::filesystem::path& path) {
  write_file_atomically(path, [&](std::ostream& out) {
    out << "# filename x y level\n" << std::setprecision(17);
    for (const auto& v : views) {
      const bool any = std::any_of(v.corners.begin(), v.corners.end(), [](auto& c) { return c.z() >= 0; });
      if (!any) {
        out << v.image << " - - -\n";
        continue;
      }
      for (const auto& c : v.corners) {
        if (c.z() < 0)
          out << v.image << " - - -\n";
        else
          out << v.image << ' ' << c.x() << ' ' << c.y() << ' ' << (c.z() == 1 ? 0.0 : -std::log2(c.z()))
              << '\n';
      }
    }
  });
}

CameraModel camera_from_opencv_yaml(const std::filesystem::path& path) {
  const std::string file = path.string();
  if (!std::filesystem::exists(path)) throw InputError(file, "", "does not exist", "check the path");
  cv::FileStorage fs;
  try {
    if (!fs.open(file, cv::FileStorage::READ))
      throw InputError(file, "", "cannot be read as an OpenCV YAML/XML file");
  } catch (const cv::Exception& e) {
    throw InputError(file, "", "is not a valid OpenCV YAML/XML file: " + std::string(e.err));
  }
  cv::Mat K, D;
  int w = 0, h = 0;
  try {
    fs["camera_matrix"] >> K;
    fs["distortion_coefficients"] >> D;
    fs["image_width"] >> w;
    fs["image_height"] >> h;
  } catch (const cv::Exception& e) {
    throw InputError(file, "", "has a malformed entry: " + std::string(e.err));
  }
  if (K.empty() || K.rows != 3 || K.cols != 3)
    throw InputError(file, "key 'camera_matrix'", "must be a 3 x 3 matrix (!!opencv-matrix)",
                     "as cv::FileStorage writes it");
  if (w <= 0 || h <= 0)
    throw InputError(file, "key 'image_width'/'image_height'",
                     "must be positive integers (the calibrated image size)");
  K.convertTo(K, CV_64F);
  if (std::abs(K.at<double>(0, 1)) > 1e-12 * std::abs(K.at<double>(0, 0)) || K.at<double>(1, 0) != 0 ||
      K.at<double>(2, 0) != 0 || K.at<double>(2, 1) != 0 || K.at<double>(2, 2) != 1)
    throw InputError(file, "key 'camera_matrix'",
                     "must be [fx 0 cx; 0 fy cy; 0 0 1]: skew is not supported by mrcal");
  std::vector<double> d;
  if (!D.empty()) {
    D.convertTo(D, CV_64F);
    d.assign(D.begin<double>(), D.end<double>());
  }
  CameraModel m;
  m.width = w;
  m.height = h;
  m.path = path;
  m.intrinsics = {K.at<double>(0, 0), K.at<double>(1, 1), K.at<double>(0, 2), K.at<double>(1, 2)};
  const bool all_zero = std::all_of(d.begin(), d.end(), [](double x) { return x == 0; });
  if (all_zero)
    m.lensmodel = "LENSMODEL_PINHOLE";
  else if (d.size() == 4 || d.size() == 5 || d.size() == 8 || d.size() == 12)
    m.lensmodel = "LENSMODEL_OPENCV" + std::to_string(d.size());
  else
    throw InputError(file, "key 'distortion_coefficients'",
                     "has " + std::to_string(d.size()) +
                         " values; mrcal has OpenCV models with 4, 5, 8 or 12 (the "
                         "14-value tilted model is not supported)");
  if (!all_zero) m.intrinsics.insert(m.intrinsics.end(), d.begin(), d.end());
  m.validate();
  return m;
}

}  // namespace clearfit
