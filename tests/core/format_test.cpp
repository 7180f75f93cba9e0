// Numbers as text (clearfit/format.hpp) against hand-worked cases and against the
// std::ostream formatting the modules' own formatters used before they moved to core.
#include <gtest/gtest.h>
#include <clearfit/format.hpp>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <sstream>

using namespace clearfit;

namespace {

std::string ostream_general(double v, int digits) {
  std::ostringstream s;
  s.precision(digits);
  s << v;
  return s.str();
}

std::string ostream_fixed(double v, int digits) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << v;
  return s.str();
}

}  // namespace

TEST(Format, SignificantDigitsByHand) {
  EXPECT_EQ(significant_digits(1234.5, 3), "1.23e+03");  // 3 digits cannot hold 1234: exponent form
  EXPECT_EQ(significant_digits(1234.4, 4), "1234");
  EXPECT_EQ(significant_digits(0.5, 3), "0.5");  // trailing zeros dropped
  EXPECT_EQ(significant_digits(0.000123456, 3), "0.000123");
  EXPECT_EQ(significant_digits(0.0000123456, 3), "1.23e-05");  // exponent below -4: exponent form
  EXPECT_EQ(significant_digits(-2.0 / 3.0, 4), "-0.6667");
  EXPECT_EQ(significant_digits(1e6, 10), "1000000");
  EXPECT_EQ(significant_digits(0.0, 3), "0");
}

TEST(Format, FixedDigitsByHand) {
  EXPECT_EQ(fixed_digits(2.345, 1), "2.3");
  EXPECT_EQ(fixed_digits(-0.001, 2), "-0.00");  // the sign stays, as printf prints it
  EXPECT_EQ(fixed_digits(12.0, 0), "12");
  EXPECT_EQ(fixed_digits(0.125, 4), "0.1250");
  EXPECT_EQ(fixed_digits(1e300, 2).size(), 301u + 3u);  // longer than any fixed buffer: 301 digits, ".00"
}

TEST(Format, NotFiniteNumbersPrintWhatTheCallerAsks) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(fixed_digits(nan, 2, ""), "");
  EXPECT_EQ(fixed_digits(-inf, 2, "-"), "-");
  EXPECT_EQ(significant_digits(inf, 4, "\xE2\x80\x94"), "\xE2\x80\x94");
  EXPECT_EQ(fixed_digits(1.26, 1, "-"), "1.3");  // finite: the number
  EXPECT_EQ(significant_digits(nan, 3), "nan");  // without a replacement, printf's text
}

TEST(Format, SameTextAsTheStreamFormattersItReplaced) {
  // Random magnitudes from 1e-9 to 1e9, both signs, every precision the modules used.
  std::mt19937_64 rng(20261127);
  std::printf("  seed 20261127\n");
  std::uniform_real_distribution<double> mantissa(-10, 10);
  std::uniform_int_distribution<int> exponent(-9, 9);
  for (int i = 0; i < 20000; ++i) {
    const double v = mantissa(rng) * std::pow(10.0, exponent(rng));
    for (int digits : {1, 2, 3, 4, 5, 6, 7, 10}) {
      ASSERT_EQ(significant_digits(v, digits), ostream_general(v, digits)) << v << " with " << digits;
      ASSERT_EQ(fixed_digits(v, digits), ostream_fixed(v, digits)) << v << " with " << digits;
    }
  }
}
