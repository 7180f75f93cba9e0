#include <clearfit/npy.hpp>

#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>

#include <fstream>
#include <regex>

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

Float32Array read_float32(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string(), "", "cannot be opened", "give a NumPy .npy file");
  char magic[8] = {};
  in.read(magic, 8);
  if (!in || std::string(magic, 6) != "\x93NUMPY" || (magic[6] != 1 && magic[6] != 2 && magic[6] != 3))
    throw InputError(path.string(), "header", "is not a NumPy .npy file");
  std::size_t len = 0;
  unsigned char b[4] = {};
  in.read(reinterpret_cast<char*>(b), magic[6] == 1 ? 2 : 4);
  len = magic[6] == 1 ? (b[0] | b[1] << 8) : (b[0] | b[1] << 8 | b[2] << 16 | static_cast<std::size_t>(b[3]) << 24);
  if (!in || len > (1u << 20)) throw InputError(path.string(), "header", "is truncated or malformed");
  std::string header(len, '\0');
  in.read(header.data(), static_cast<std::streamsize>(len));
  std::smatch m;
  if (!std::regex_search(header, m, std::regex("'descr':\\s*'([^']*)'")) || (m[1] != "<f4" && m[1] != "f4"))
    throw InputError(path.string(), "header", "does not hold little-endian float32 ('<f4')", "save it with dtype=numpy.float32");
  if (!std::regex_search(header, m, std::regex("'fortran_order':\\s*False")))
    throw InputError(path.string(), "header", "is in Fortran order", "save a C-ordered array");
  if (!std::regex_search(header, m, std::regex("'shape':\\s*\\(([^)]*)\\)")))
    throw InputError(path.string(), "header", "has no shape");
  Float32Array a;
  std::size_t count = 1;
  const std::string dims = m[1];
  static const std::regex number("[0-9]+");
  for (std::sregex_iterator it(dims.begin(), dims.end(), number), end; it != end; ++it) {
    a.shape.push_back(std::stoull(it->str()));
    count *= a.shape.back();
  }
  if (count > (std::size_t{1} << 32)) throw InputError(path.string(), "shape", "is too large");
  a.values.resize(count);
  in.read(reinterpret_cast<char*>(a.values.data()), static_cast<std::streamsize>(count * sizeof(float)));
  if (static_cast<std::size_t>(in.gcount()) != count * sizeof(float))
    throw InputError(path.string(), "data", "is truncated: the header promises " + std::to_string(count) + " floats");
  return a;
}

}  // namespace clearfit::npy
