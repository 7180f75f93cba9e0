#pragma once
// Numbers as text, for every module's messages, tables and reports: one home for the two formats
// clearfit prints numbers in. Both are printf's conversions in the "C" locale (as std::ostream's
// defaults and std::fixed are), so a number prints the same wherever it is printed.
#include <string>
#include <string_view>

namespace clearfit {

/// `v` with `digits` significant digits, as printf's "%.*g" (and an ostream's default with
/// precision(digits)): trailing zeros dropped, the exponent form for very small or large values.
/// significant_digits(1234.5, 3) == "1.23e+03", significant_digits(0.5, 3) == "0.5". NaN prints "nan".
std::string significant_digits(double v, int digits);
/// The same, but `not_finite` for NaN and infinities (tables and reports never show "nan").
std::string significant_digits(double v, int digits, std::string_view not_finite);

/// `v` with `digits` decimals, as printf's "%.*f" (and std::fixed with precision(digits)):
/// fixed_digits(2.345, 1) == "2.3", fixed_digits(-0.001, 2) == "-0.00". NaN prints "nan".
std::string fixed_digits(double v, int digits);
/// The same, but `not_finite` for NaN and infinities.
std::string fixed_digits(double v, int digits, std::string_view not_finite);

}  // namespace clearfit
