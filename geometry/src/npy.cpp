#include <clearfit/npy.hpp>

#include <clearfit/atomic_file.hpp>

#include <bit>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace clearfit::npy {

static_assert(std::endian::native == std::endian::little, "the .npy writer assumes a little-endian host");

void write_float32(const std::filesystem::path& path, const std::vector<std::size_t>& shape,
                   const std::function<void(std::size_t, float*)>& fill_row) {
  if (shape.empty()) throw std::invalid_argument("npy::write_float32: empty shape");
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (";
  std::size_t row_size = 1;
  for (std::size_t k = 0; k < shape.size(); ++k) {
    header += std::to_string(shape[k]) + (shape.size() == 1 || k + 1 < shape.size() ? ", " : "");
    if (k > 0) row_size *= shape[k];
  }
  header += "), }";
  const std::size_t unpadded = 10 + header.size() + 1;  // magic(6) + version(2) + length(2) + '\n'
  header.append((64 - unpadded % 64) % 64, ' ');
  header.push_back('\n');
  write_file_atomically(path, [&](std::ostream& out) {
    out.write("\x93NUMPY\x01\x00", 8);
    const auto len = static_cast<std::uint16_t>(header.size());
    const char le[2] = {static_cast<char>(len & 0xff), static_cast<char>(len >> 8)};
    out.write(le, 2);
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    std::vector<float> row(row_size);
    for (std::size_t r = 0; r < shape[0]; ++r) {
      fill_row(r, row.data());
      out.write(reinterpret_cast<const char*>(row.data()),
                static_cast<std::streamsize>(row.size() * sizeof(float)));
    }
  });
}

}  // namespace clearfit::npy
