// .cameramodel files: reading (mrcal's parser), validation, writing (our own
// full-precision writer), and the intrinsics hash.
#include "mrcal_api.hpp"
#include "stderr_capture.hpp"

#include <clearfit/atomic_file.hpp>
#include <clearfit/camera/projection_uncertainty.hpp>
#include <clearfit/error.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string_view>

namespace clearfit {
namespace detail {

std::optional<Lens> parse_lens(const std::string& name) {
  Lens lens;
  if (!mrcal_lensmodel_from_name(&lens.model, name.c_str()) || !mrcal_lensmodel_type_is_valid(lens.model.type))
    return std::nullopt;
  lens.num_params = mrcal_lensmodel_num_params(&lens.model);
  const mrcal_lensmodel_metadata_t meta = mrcal_lensmodel_metadata(&lens.model);
  lens.can_project_behind_camera = meta.can_project_behind_camera;
  lens.has_gradients = meta.has_gradients;
  switch (lens.model.type) {
    case MRCAL_LENSMODEL_PINHOLE: lens.special = Lens::Special::pinhole; break;
    case MRCAL_LENSMODEL_STEREOGRAPHIC: lens.special = Lens::Special::stereographic; break;
    case MRCAL_LENSMODEL_LONLAT: lens.special = Lens::Special::lonlat; break;
    case MRCAL_LENSMODEL_LATLON: lens.special = Lens::Special::latlon; break;
    default: lens.special = Lens::Special::none;
  }
  return lens;
}

Lens lens_or_throw(const std::string& name) {
  auto lens = parse_lens(name);
  if (!lens || lens->model.type == MRCAL_LENSMODEL_CAHVORE)
    throw std::invalid_argument("clearfit camera: unsupported lens model '" + name + "' (validate the model first)");
  return *lens;
}

}  // namespace detail

namespace {

struct Problem {
  std::string key, problem, hint;
};

std::string supported_models_hint() {
  std::string s = "supported: ";
  bool first = true;
  for (const char* const* p = mrcal_supported_lensmodel_names(); *p; ++p) {
    if (std::strstr(*p, "CAHVORE")) continue;
    s += (first ? "" : ", ") + std::string(*p);
    first = false;
  }
  return s;
}

// Why the lens model name is unusable, or nullopt.
std::optional<Problem> lens_problem(const std::string& name) {
  const auto lens = detail::parse_lens(name);
  if (!lens) {
    if (mrcal_lensmodel_type_is_valid(mrcal_lensmodel_type_from_name(name.c_str())))
      return Problem{"lensmodel", "'" + name + "' has a missing or malformed configuration",
                     "e.g. LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=30_Ny=20_fov_x_deg=120"};
    return Problem{"lensmodel", "unknown lens model '" + name + "'", supported_models_hint()};
  }
  if (lens->model.type == MRCAL_LENSMODEL_CAHVORE)
    return Problem{"lensmodel", "'" + name + "' is not supported (mrcal cannot unproject CAHVORE)",
                   "recalibrate with another model, e.g. LENSMODEL_OPENCV8 or a splined model"};
  return std::nullopt;
}

std::optional<Problem> find_problem(const CameraModel& m) {
  if (auto p = lens_problem(m.lensmodel)) return p;
  const detail::Lens lens = *detail::parse_lens(m.lensmodel);
  if (static_cast<int>(m.intrinsics.size()) != lens.num_params)
    return Problem{"intrinsics",
                   "has " + std::to_string(m.intrinsics.size()) + " values; " + m.lensmodel + " needs " +
                       std::to_string(lens.num_params),
                   "fx, fy, cx, cy, then the distortion parameters"};
  for (std::size_t i = 0; i < m.intrinsics.size(); ++i)
    if (!std::isfinite(m.intrinsics[i]))
      return Problem{"intrinsics", "value " + std::to_string(i) + " is not a finite number", ""};
  if (!(m.intrinsics[0] > 0 && m.intrinsics[1] > 0))
    return Problem{"intrinsics", "the focal lengths fx, fy must be positive", ""};
  if (m.width <= 0 || m.height <= 0)
    return Problem{"imagersize",
                   "must be two positive integers, found " + std::to_string(m.width) + " x " +
                       std::to_string(m.height),
                   ""};
  // Bounded before anything per pixel is allocated (a map, an image).
  if (m.width > CameraModel::kMaxImagerSide || m.height > CameraModel::kMaxImagerSide ||
      static_cast<std::int64_t>(m.width) * m.height > CameraModel::kMaxImagerPixels)
    return Problem{"imagersize",
                   std::to_string(m.width) + " x " + std::to_string(m.height) + " is larger than any camera's imager (at most " +
                       std::to_string(CameraModel::kMaxImagerSide) + " px a side and " + std::to_string(CameraModel::kMaxImagerPixels / 1000000) + " Mpx)",
                   "give the image size in pixels the camera was calibrated at"};
  if (!m.cam_from_part.rotation.allFinite() || !m.cam_from_part.translation.allFinite())
    return Problem{"extrinsics", "is not finite", ""};
  // The imager size must belong to this lens: a principal point more than half
  // the imager outside it means the size and the intrinsics disagree (a model
  // calibrated at another resolution, or a wrong imagersize).
  const double cx = m.intrinsics[2], cy = m.intrinsics[3];
  if (cx < -0.5 - 0.5 * m.width || cx > m.width - 0.5 + 0.5 * m.width || cy < -0.5 - 0.5 * m.height ||
      cy > m.height - 0.5 + 0.5 * m.height)
    return Problem{"imagersize",
                   std::to_string(m.width) + " x " + std::to_string(m.height) +
                       " does not fit the lens: its principal point (" + std::to_string(cx) + ", " +
                       std::to_string(cy) + ") lies far outside the imager",
                   "use the image size the camera was calibrated at"};
  return std::nullopt;
}

// "line N, key 'k'" when the key is found in the text, else "key 'k'".
std::string locate_key(const std::string& text, const std::string& key) {
  for (const char quote : {'\'', '"'}) {
    const std::string needle = quote + key + quote;
    const auto at = text.find(needle);
    if (at != std::string::npos) {
      const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n');
      return "line " + std::to_string(line) + ", key '" + key + "'";
    }
  }
  return "key '" + key + "'";
}

// The text after "'key':" up to the end of its value, or "" (a light scan used
// only to explain why mrcal's parser refused a file).
std::string raw_value(const std::string& text, const std::string& key) {
  for (const char quote : {'\'', '"'}) {
    auto at = text.find(quote + key + quote);
    if (at == std::string::npos) continue;
    at = text.find(':', at + key.size() + 2);
    if (at == std::string::npos) return "";
    ++at;
    while (at < text.size() && std::isspace(static_cast<unsigned char>(text[at]))) ++at;
    if (at >= text.size()) return "";
    if (text[at] == '\'' || text[at] == '"') {
      const auto end = text.find(text[at], at + 1);
      return end == std::string::npos ? "" : text.substr(at + 1, end - at - 1);
    }
    if (text[at] == '[') {
      const auto end = text.find(']', at);
      return end == std::string::npos ? "" : text.substr(at + 1, end - at - 1);
    }
  }
  return "";
}

int count_list_items(const std::string& list) {
  int n = 0;
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.find_first_not_of(" \t\r\n") != std::string::npos) ++n;
  }
  return n;
}

// mrcal's parse messages joined, each byte offset "at N" given as the line it falls on.
std::string parser_says(const std::string& text, const std::vector<std::string>& messages) {
  std::string out;
  for (std::string m : messages) {
    const auto at = m.rfind(" at ");
    if (at != std::string::npos && at + 4 < m.size() && m.find_first_not_of("0123456789", at + 4) == std::string::npos) {
      const std::size_t byte = std::min<std::size_t>(std::strtoull(m.c_str() + at + 4, nullptr, 10), text.size());
      m.replace(at, std::string::npos, " on line " + std::to_string(1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(byte), '\n')));
    }
    out += (out.empty() ? "" : "; ") + m;
  }
  return out;
}

// Explains why mrcal could not read the file (`said`: what mrcal's parser printed).
InputError explain_parse_failure(const std::string& file, const std::string& text, const std::vector<std::string>& said) {
  const std::string lens = raw_value(text, "lensmodel");
  if (lens.empty())
    return InputError(file, "", "is not an mrcal .cameramodel file (no 'lensmodel' key could be read)",
                      "write it with mrcal-calibrate-cameras, mrcal's Python cameramodel.write() or clearfit");
  if (auto p = lens_problem(lens)) return InputError(file, locate_key(text, p->key), p->problem, p->hint);
  const int expected = detail::parse_lens(lens)->num_params;
  const int found = count_list_items(raw_value(text, "intrinsics"));
  if (found != expected)
    return InputError(file, locate_key(text, "intrinsics"),
                      "has " + std::to_string(found) + " values; " + lens + " needs " + std::to_string(expected),
                      "fx, fy, cx, cy, then the distortion parameters");
  for (const char* key : {"extrinsics", "imagersize"})
    if (locate_key(text, key).rfind("line", 0) != 0)
      return InputError(file, std::string("key '") + key + "'", "is missing");
  const std::string size = raw_value(text, "imagersize");
  std::stringstream ss(size);
  std::string item;
  int items = 0;
  while (std::getline(ss, item, ',')) {
    if (item.find_first_not_of(" \t\r\n") == std::string::npos) continue;
    ++items;
    char* end = nullptr;
    const long v = std::strtol(item.c_str(), &end, 10);
    if (v <= 0 || end == item.c_str() || std::string_view(end).find_first_not_of(" \t\r\n") != std::string_view::npos)
      return InputError(file, locate_key(text, "imagersize"), "must be two positive integers (width, height), found [" + size + "]");
  }
  if (items != 2)
    return InputError(file, locate_key(text, "imagersize"), "must be two positive integers (width, height), found [" + size + "]");
  return InputError(file, "", "mrcal cannot parse this .cameramodel file" + (said.empty() ? std::string() : ": " + parser_says(text, said)),
                    "compare it with a file written by mrcal's Python cameramodel.write()");
}

struct ModelDeleter {
  void operator()(mrcal_cameramodel_t* m) const { mrcal_free_cameramodel(&m); }
};

void append_double(std::string& out, double x) {
  std::array<char, 32> buf{};
  const auto res = std::to_chars(buf.data(), buf.data() + buf.size(), x);  // shortest exact round trip
  out.append(buf.data(), res.ptr);
}

std::string list_of(const double* values, std::size_t n) {
  std::string s = "[ ";
  for (std::size_t i = 0; i < n; ++i) {
    append_double(s, values[i]);
    s += ", ";
  }
  s += "]";
  return s;
}

std::uint64_t fnv1a(std::uint64_t h, const void* data, std::size_t n) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= 1099511628211ull;
  }
  return h;
}

std::uint64_t fnv1a_u64(std::uint64_t h, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) {  // fixed byte order: the key is the same on every machine
    h ^= (v >> (8 * i)) & 0xffu;
    h *= 1099511628211ull;
  }
  return h;
}

}  // namespace

void CameraModel::validate() const {
  if (auto p = find_problem(*this)) throw InputError(path.string(), "key '" + p->key + "'", p->problem, p->hint);
}

std::uint64_t CameraModel::intrinsics_hash() const {
  std::uint64_t h = 14695981039346656037ull;
  h = fnv1a(h, lensmodel.data(), lensmodel.size());
  h = fnv1a_u64(h, intrinsics.size());
  for (double x : intrinsics) {
    if (x == 0.0) x = 0.0;  // -0.0 and 0.0 give the same rays
    std::uint64_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    h = fnv1a_u64(h, bits);
  }
  h = fnv1a_u64(h, static_cast<std::uint32_t>(width));
  h = fnv1a_u64(h, static_cast<std::uint32_t>(height));
  return h;
}

namespace {
// True if `text` (a Python-literal dict as in .cameramodel files, with #
// comments) has closed quotes, balanced (), [], {}, and ends with the '}'
// that closes its first '{'.
bool balanced_python_literal(const std::string& text) {
  std::string stack;
  char quote = 0;
  bool seen_open = false, closed = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quote) {
      if (c == '\\') ++i;
      else if (c == quote) quote = 0;
      continue;
    }
    if (closed && !std::isspace(static_cast<unsigned char>(c)) && c != '#') return false;
    if (c == '#') {
      while (i < text.size() && text[i] != '\n') ++i;
      continue;
    }
    if (c == '\'' || c == '"') quote = c;
    else if (c == '{' || c == '[' || c == '(') {
      seen_open |= c == '{';
      stack.push_back(c == '{' ? '}' : c == '[' ? ']' : ')');
    } else if (c == '}' || c == ']' || c == ')') {
      if (stack.empty() || stack.back() != c) return false;
      stack.pop_back();
      closed = stack.empty();
    }
  }
  return quote == 0 && seen_open && closed && stack.empty();
}
}  // namespace

CameraModel read_cameramodel(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(file, "", std::filesystem::exists(path, ec) ? "is not a file" : "does not exist",
                     "give the path of an mrcal .cameramodel file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(file, "", "cannot be opened", "check its permissions");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  if (text.size() > static_cast<std::size_t>(std::numeric_limits<int>::max()))
    throw InputError(file, "", "is too large for a .cameramodel file");
  if (text.empty()) throw InputError(file, "", "is empty", "give the path of an mrcal .cameramodel file");

  // mrcal 2.2's parser reads past the end of a truncated text (an unclosed
  // string or list: a crash under AddressSanitizer). Only well-formed text is
  // handed to it: quotes closed, brackets balanced, ending with the closing '}'.
  if (!balanced_python_literal(text)) throw explain_parse_failure(file, text, {});
  // mrcal's parser prints why it refuses a text on stderr: taken into the error instead.
  mrcal_cameramodel_t* parsed = nullptr;
  const std::string said = detail::capture_stderr([&] { parsed = mrcal_read_cameramodel_string(text.data(), static_cast<int>(text.size())); });
  std::unique_ptr<mrcal_cameramodel_t, ModelDeleter> m(parsed);
  if (!m) throw explain_parse_failure(file, text, detail::mrcal_messages(said));
  std::fputs(said.c_str(), stderr);  // nothing from mrcal on success; another thread's output, shown as it was

  CameraModel model;
  model.path = path;
  std::array<char, 1024> name{};
  if (!mrcal_lensmodel_name(name.data(), static_cast<int>(name.size()), &m->lensmodel))
    throw InputError(file, locate_key(text, "lensmodel"), "mrcal cannot name this lens model");
  model.lensmodel = name.data();
  if (auto p = lens_problem(model.lensmodel)) throw InputError(file, locate_key(text, p->key), p->problem, p->hint);
  const int n = mrcal_lensmodel_num_params(&m->lensmodel);
  model.intrinsics.assign(m->intrinsics, m->intrinsics + n);
  model.width = static_cast<int>(m->imagersize[0]);
  model.height = static_cast<int>(m->imagersize[1]);
  std::array<double, 6> rt;
  std::copy(m->rt_cam_ref, m->rt_cam_ref + 6, rt.begin());
  for (double x : rt)
    if (!std::isfinite(x)) throw InputError(file, locate_key(text, "extrinsics"), "is not finite");
  model.cam_from_part = Rigid3::from_rt(rt);
  if (m->imagersize[0] > static_cast<unsigned>(std::numeric_limits<int>::max()) ||
      m->imagersize[1] > static_cast<unsigned>(std::numeric_limits<int>::max()))
    throw InputError(file, locate_key(text, "imagersize"), "is too large");
  if (auto p = find_problem(model)) throw InputError(file, locate_key(text, p->key), p->problem, p->hint);
  return model;
}

std::string cameramodel_text(const CameraModel& model, const std::filesystem::path& path) {
  if (auto p = find_problem(model))
    throw std::invalid_argument("write_cameramodel(" + path.string() + "): key '" + p->key + "' " + p->problem);
  const auto rt = model.cam_from_part.to_rt();
  std::string s;
  s += "# mrcal .cameramodel written by clearfit\n{\n";
  s += "    'lensmodel':  '" + model.lensmodel + "',\n\n";
  s += "    # intrinsics are fx,fy,cx,cy,distortion0,distortion1,....\n";
  s += "    'intrinsics': " + list_of(model.intrinsics.data(), model.intrinsics.size()) + ",\n\n";
  s += "    # extrinsics are rt_fromref; the reference is the part frame (cam_from_part):\n";
  s += "    # r is a Rodrigues vector in radians, t in millimetres\n";
  s += "    'extrinsics': " + list_of(rt.data(), rt.size()) + ",\n\n";
  s += "    'imagersize': [ " + std::to_string(model.width) + ", " + std::to_string(model.height) + ", ],\n}\n";
  return s;
}

void write_cameramodel(const CameraModel& model, const std::filesystem::path& path) {
  write_file_atomically(path, cameramodel_text(model, path));
}

}  // namespace clearfit
