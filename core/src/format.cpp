#include <clearfit/format.hpp>

#include <cmath>
#include <cstdio>

namespace clearfit {
namespace {

enum class Conversion { general, fixed };

std::string printed(Conversion c, double v, int digits) {
  const char* format = c == Conversion::general ? "%.*g" : "%.*f";
  char buf[64];
  const int n = std::snprintf(buf, sizeof buf, format, digits, v);
  if (n < 0) return {};
  if (n < static_cast<int>(sizeof buf)) return std::string(buf, static_cast<std::size_t>(n));
  std::string s(static_cast<std::size_t>(n), '\0');  // a long fixed-point number (1e300 with "%.2f")
  std::snprintf(s.data(), s.size() + 1, format, digits, v);
  return s;
}

}  // namespace

std::string significant_digits(double v, int digits) { return printed(Conversion::general, v, digits); }

std::string significant_digits(double v, int digits, std::string_view not_finite) {
  return std::isfinite(v) ? significant_digits(v, digits) : std::string(not_finite);
}

std::string fixed_digits(double v, int digits) { return printed(Conversion::fixed, v, digits); }

std::string fixed_digits(double v, int digits, std::string_view not_finite) {
  return std::isfinite(v) ? fixed_digits(v, digits) : std::string(not_finite);
}

}  // namespace clearfit
