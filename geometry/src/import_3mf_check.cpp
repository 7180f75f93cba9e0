// The zip package of a 3MF, checked before lib3mf reads it. lib3mf 1.8 takes
// each entry's sizes as its zip headers state them and streams what libzip
// unpacks: an entry that unpacks to more than it declares (a "zip bomb" behind
// a small header) or declares more than its packed bytes can hold reaches the
// XML parser unchecked. Here every entry's declared (unpacked) size is bounded
// by what its packed bytes can give (stored: the same bytes; deflate: at most
// 1032 bytes per packed byte) and the package's total by kMaxUnpackedBytes,
// then each entry is unpacked once, counting, and must give exactly what it
// declares. Nothing larger than a 64 KiB buffer is allocated on the way.
#include "import_internal.hpp"

#include <zip.h>

#include <array>
#include <memory>

namespace clearfit::detail {
namespace {

/// The most a 3MF may unpack to in all, in bytes: 4 GiB, some 40 million
/// triangles written as 3MF XML, beyond any part clearfit fits.
constexpr std::uint64_t kMaxUnpackedBytes = std::uint64_t{4} << 30;
/// Deflate's largest expansion: a 258-byte match coded in 2 bits (1032 to 1),
/// plus room for an entry's few bytes of block headers.
constexpr std::uint64_t kDeflateMaxRatio = 1032;
constexpr std::uint64_t kDeflateSlackBytes = 1024;

struct ZipCloser {
  void operator()(zip_t* z) const { zip_discard(z); }
};
struct ZipFileCloser {
  void operator()(zip_file_t* f) const { zip_fclose(f); }
};

constexpr const char* kHint = "the package is damaged or not made by a 3MF writer; export the part again";

std::string entry_of(const zip_stat_t& st, zip_uint64_t index) {
  if ((st.valid & ZIP_STAT_NAME) && st.name) return "zip entry '" + std::string(st.name) + "'";
  return "zip entry " + std::to_string(index);
}

/// Checks what the entry's headers claim; returns its declared unpacked size.
std::uint64_t check_declared(const zip_stat_t& st, const std::string& name, const std::string& entry) {
  const bool sized = (st.valid & ZIP_STAT_SIZE) && (st.valid & ZIP_STAT_COMP_SIZE) && (st.valid & ZIP_STAT_COMP_METHOD);
  if (!sized) throw InputError(name, entry, "its zip header gives no sizes", kHint);
  const std::uint64_t size = st.size, packed = st.comp_size;
  const std::string claim = "declares " + std::to_string(size) + " bytes unpacked from " + std::to_string(packed) + " packed bytes";
  if (st.comp_method == ZIP_CM_STORE && size != packed)
    throw InputError(name, entry, claim + ", but it is stored (not compressed): the two must be equal", kHint);
  if (st.comp_method == ZIP_CM_DEFLATE && size > kDeflateSlackBytes && (size - kDeflateSlackBytes) / kDeflateMaxRatio > packed)
    throw InputError(name, entry, claim + ", more than deflate can unpack from them (at most 1032 bytes per byte)", kHint);
  if (size > kMaxUnpackedBytes)
    throw InputError(name, entry, claim + ", more than clearfit reads from one 3MF (" + std::to_string(kMaxUnpackedBytes) + " bytes)",
                     "a part this large is beyond what clearfit fits: simplify the mesh");
  return size;
}

/// Unpacks the entry once, counting, without keeping it: it must give exactly `declared` bytes.
void check_unpacked(zip_t* zip, zip_uint64_t index, std::uint64_t declared, const std::string& name, const std::string& entry) {
  std::unique_ptr<zip_file_t, ZipFileCloser> file(zip_fopen_index(zip, index, 0));
  if (!file) throw InputError(name, entry, std::string("cannot be unpacked: ") + zip_strerror(zip), kHint);
  std::array<char, 65536> buffer{};
  std::uint64_t got = 0;
  for (;;) {
    const zip_int64_t n = zip_fread(file.get(), buffer.data(), buffer.size());
    if (n < 0) throw InputError(name, entry, std::string("cannot be unpacked: ") + zip_file_strerror(file.get()), kHint);
    if (n == 0) break;
    got += static_cast<std::uint64_t>(n);
    if (got > declared)
      throw InputError(name, entry, "unpacks to more than the " + std::to_string(declared) + " bytes its zip header declares", kHint);
  }
  if (got != declared)
    throw InputError(name, entry, "unpacks to " + std::to_string(got) + " bytes, not the " + std::to_string(declared) +
                                      " its zip header declares", kHint);
}

}  // namespace

void check_3mf_package(const std::filesystem::path& path, const std::string& name) {
  int error = 0;
  std::unique_ptr<zip_t, ZipCloser> zip(zip_open(path.string().c_str(), ZIP_RDONLY, &error));
  if (!zip) return;  // not a zip package at all: lib3mf says so in its own words
  const zip_int64_t entries = zip_get_num_entries(zip.get(), 0);
  std::uint64_t total = 0;
  for (zip_int64_t i = 0; i < entries; ++i) {
    const auto index = static_cast<zip_uint64_t>(i);
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_stat_index(zip.get(), index, 0, &st) != 0)
      throw InputError(name, "zip entry " + std::to_string(i), std::string("cannot be read: ") + zip_strerror(zip.get()), kHint);
    const std::string entry = entry_of(st, index);
    const std::uint64_t size = check_declared(st, name, entry);
    total += size;
    if (total > kMaxUnpackedBytes)
      throw InputError(name, entry, "brings the package's unpacked size to " + std::to_string(total) +
                                        " bytes, more than clearfit reads from one 3MF (" + std::to_string(kMaxUnpackedBytes) + " bytes)",
                       "a part this large is beyond what clearfit fits: simplify the mesh");
  }
  for (zip_int64_t i = 0; i < entries; ++i) {
    const auto index = static_cast<zip_uint64_t>(i);
    zip_stat_t st;
    zip_stat_init(&st);
    zip_stat_index(zip.get(), index, 0, &st);
    check_unpacked(zip.get(), index, st.size, name, entry_of(st, index));
  }
}

}  // namespace clearfit::detail
