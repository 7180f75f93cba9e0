#pragma once
// The only place that includes mrcal (its C API is not stable across major
// releases; code against Debian's 2.2). Private to camera/src.
// mrcal's headers have no extern "C" guard; mrcal-image.h is not C++ and is
// never included.
extern "C" {
#include <mrcal/mrcal.h>
}

#include <clearfit/camera/camera_model.hpp>

#include <optional>
#include <string>

namespace clearfit::detail {

/// A parsed lens model plus the facts the wrappers need.
struct Lens {
  mrcal_lensmodel_t model{};
  int num_params = 0;
  bool can_project_behind_camera = false;
  bool has_gradients = false;
  /// Which closed form mrcal has for this model (nullopt: the general routines).
  enum class Special { none, pinhole, stereographic, lonlat, latlon } special = Special::none;
};

/// Parses a full lens model name; nullopt when mrcal does not know it (or its
/// configuration is missing or malformed).
std::optional<Lens> parse_lens(const std::string& name);

/// Parses and checks `name`; throws std::invalid_argument when it is invalid
/// (models reaching projection have passed CameraModel::validate()).
Lens lens_or_throw(const std::string& name);

}  // namespace clearfit::detail
