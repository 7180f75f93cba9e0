#pragma once
// The camera's projection uncertainty as clearfit carries it in a .cameramodel:
// mrcal's method (calibrate.hpp: the calibration's state covariance through
// dq/db; 1-σ in pixels in the worst direction) sampled on a grid over the
// imager, for points at one distance from the camera. Three keys that mrcal's
// readers (C and Python) skip:
//   'clearfit_uncertainty_nodes': [ nx, ny, ],
//   'clearfit_uncertainty_distance_mm': d,
//   'clearfit_uncertainty_px': [ nx·ny values, row-major, ],
// The nodes span the imager edge to edge, its corner pixels included: node i of
// nx lies at x = i·(W − 1)/(nx − 1) (mrcal.sample_imager's grid), so the σ where
// the model extrapolates most, at the image's edges and corners, is in the map.
// Models written before carry 'clearfit_uncertainty_cells': [ nx, ny, ] instead
// of the nodes key: the values sit at the centres of nx × ny cells,
// (c + 0.5)·W/nx − 0.5, and are read as before (held beyond the outer centres).
// `clearfit calibrate` writes them; a model from elsewhere has none (its
// projection uncertainty is then unknown to clearfit: the σ has no term for it).
#include <clearfit/camera/camera_model.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace clearfit {

struct ProjectionUncertainty {
  /// Where the values sit (the header's comment): `nodes` edge to edge, `cells` at cell centres (older files).
  enum class Layout { nodes, cells };
  int nx = 0, ny = 0;      ///< nodes (or cells) across, down
  double distance_mm = 0;  ///< the distance the uncertainty was evaluated at
  std::vector<double> px;  ///< nx · ny values, row-major, 1-σ in pixels (worst direction)
  Layout layout = Layout::nodes;
  /// 1-σ (px) at `pixel` of a width × height imager: bilinear between the grid's points,
  /// the nearest edge's beyond them (outside the imager for nodes, beyond the outer centres for cells).
  double at(const Vec2& pixel, int width, int height) const;
  double largest() const;
  /// Whether the grid and values are usable: nodes >= 2 (cells >= 1) each way, nx·ny values >= 0 and finite,
  /// distance > 0.
  bool valid() const;
};

/// The pixels (row-major, nx · ny) at which a width × height imager's uncertainty is sampled in `layout`.
std::vector<Vec2> uncertainty_sample_pixels(ProjectionUncertainty::Layout layout, int nx, int ny, int width, int height);

/// The keys above from a .cameramodel file (nodes, or the older cells); nullopt when it has none. Throws
/// InputError naming the file, line and key when only some are given, both grid keys are, a count disagrees,
/// or a value is negative or not finite.
std::optional<ProjectionUncertainty> read_projection_uncertainty(const std::filesystem::path& cameramodel);

/// The .cameramodel text write_cameramodel writes to `path` (defined in camera_model.cpp). Throws
/// std::invalid_argument naming `path`, the key and its defect when the model is not valid.
std::string cameramodel_text(const CameraModel& model, const std::filesystem::path& path);

/// write_cameramodel with the uncertainty's keys (in its layout). Throws std::invalid_argument when the
/// uncertainty is not valid().
void write_cameramodel(const CameraModel& model, const ProjectionUncertainty& uncertainty, const std::filesystem::path& path);

}  // namespace clearfit
