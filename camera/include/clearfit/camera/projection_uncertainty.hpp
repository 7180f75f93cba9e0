#pragma once
// The camera's projection uncertainty as clearfit carries it in a .cameramodel:
// mrcal's method (calibrate.hpp: the calibration's state covariance through
// dq/db; 1-σ in pixels in the worst direction) sampled at the centres of a grid
// of cells over the imager, for points at one distance from the camera. Three
// keys that mrcal's readers (C and Python) skip:
//   'clearfit_uncertainty_cells': [ nx, ny, ],
//   'clearfit_uncertainty_distance_mm': d,
//   'clearfit_uncertainty_px': [ nx·ny values, row-major, ],
// `clearfit calibrate` writes them; a model from elsewhere has none (its
// projection uncertainty is then unknown to clearfit: the σ has no term for it).
#include <clearfit/camera/camera_model.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace clearfit {

struct ProjectionUncertainty {
  int cells_x = 0, cells_y = 0;
  double distance_mm = 0;  ///< the distance the uncertainty was evaluated at
  std::vector<double> px;  ///< cells_x · cells_y values, row-major, 1-σ in pixels (worst direction)
  /// 1-σ (px) at `pixel` of a width × height imager: bilinear between the cell centres
  /// ((c + 0.5)·W/nx − 0.5, as calibrate samples them), the nearest cell's beyond the outer centres.
  double at(const Vec2& pixel, int width, int height) const;
  double largest() const;
};

/// The keys above from a .cameramodel file; nullopt when it has none. Throws InputError naming the
/// file, line and key when only some are given, a count disagrees, or a value is negative or not finite.
std::optional<ProjectionUncertainty> read_projection_uncertainty(const std::filesystem::path& cameramodel);

/// The .cameramodel text write_cameramodel writes to `path` (defined in camera_model.cpp). Throws
/// std::invalid_argument naming `path`, the key and its defect when the model is not valid.
std::string cameramodel_text(const CameraModel& model, const std::filesystem::path& path);

/// write_cameramodel with the uncertainty's keys. Throws std::invalid_argument when the
/// uncertainty's counts disagree or a value is negative or not finite.
void write_cameramodel(const CameraModel& model, const ProjectionUncertainty& uncertainty, const std::filesystem::path& path);

}  // namespace clearfit
