#pragma once
// Numbers in the fit module's messages and warnings: fixed-point with a given number of digits.
#include <sstream>
#include <string>

namespace clearfit {

inline std::string fixed_digits(double v, int digits) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << v;
  return s.str();
}

}  // namespace clearfit
