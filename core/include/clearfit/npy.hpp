#pragma once
// A minimal NumPy .npy writer (format 1.0, little-endian float32, C order),
// shared by every exporter of dense float arrays (maps, chart fields).
#include <cstddef>
#include <filesystem>
#include <functional>
#include <vector>

namespace clearfit::npy {

/// Writes a float32 array of `shape` (at least one dimension) to `path`
/// atomically. `fill_row(r, out)` writes the r-th slice along the first axis
/// (product of the other dimensions floats) into `out`. Assumes a
/// little-endian host (checked at compile time).
void write_float32(const std::filesystem::path& path, const std::vector<std::size_t>& shape,
                   const std::function<void(std::size_t row, float* out)>& fill_row);


/// A float32 array read from a .npy file.
struct Float32Array {
  std::vector<std::size_t> shape;
  std::vector<float> values;  ///< C order
};
/// Reads a NumPy .npy file (format 1.x or 2.x) holding little-endian float32
/// in C order. Throws InputError naming the file and what is wrong (not .npy,
/// another dtype, Fortran order, truncated).
Float32Array read_float32(const std::filesystem::path& path);

}  // namespace clearfit::npy
