#pragma once
// A YAML map's key as text. yaml-cpp's as<std::string>() throws its own
// TypedBadConversion (an internal error, exit 1) when a key is a list, a map or
// empty (`[a]: 1`, `{a: 1}: 2`, `: 1`): the readers refuse such a key as bad
// input instead. Header-only, for the modules that read YAML (they link yaml-cpp).
#include <clearfit/error.hpp>

#include <yaml-cpp/yaml.h>

#include <string>

namespace clearfit {

/// The key's text; InputError naming `file` and the key's line when it is not plain text.
inline std::string yaml_key(const YAML::Node& key, const std::string& file) {
  if (key.IsScalar()) return key.Scalar();
  const int line = key.Mark().line;
  throw InputError(file, line >= 0 ? "line " + std::to_string(line + 1) : "", "a key is a list, a map or empty",
                   "keys are plain names, such as 'schema:'");
}

}  // namespace clearfit
