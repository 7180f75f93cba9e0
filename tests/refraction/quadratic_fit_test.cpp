// The boundary resolver's least-squares quadratic: exact on quadratics,
// refuses point sets that leave a term free.
#include <clearfit/refraction/quadratic_fit.hpp>

#include <gtest/gtest.h>

#include <cmath>

using clearfit::QuadraticFit;

namespace {
// A skin-point-like field: large offset, small curvature (mm).
Eigen::Matrix<double, 1, 2> field(int x, int y) {
  const double u = x - 1003.0, v = y - 517.0;
  return {31.2 + 0.05 * u - 0.002 * v + 3e-5 * u * u + 2e-5 * u * v - 4e-5 * v * v,
          -12.7 + 0.001 * u + 0.048 * v - 1e-5 * u * u + 5e-5 * v * v};
}
}  // namespace

TEST(QuadraticFit, ReproducesAQuadraticBetweenScatteredPoints) {
  QuadraticFit<2> fit(1004, 520, 1.0 / 8);
  // An L-shaped band of traced pixels along two edges of an 8-px cell.
  for (int y = 516; y <= 524; ++y)
    for (int x = 1000; x <= 1008; ++x)
      if (y >= 523 || x <= 1001) fit.add(x, y, field(x, y));
  ASSERT_TRUE(fit.solve());
  double worst = 0;
  for (int y = 516; y <= 524; ++y)
    for (int x = 1000; x <= 1008; ++x) worst = std::max(worst, (fit.at(x, y) - field(x, y)).norm());
  EXPECT_LT(worst, 1e-9);  // mm: rounding only
}

TEST(QuadraticFit, RefusesPointsThatLeaveATermFree) {
  // Two rows only: v² is undetermined, whatever the columns.
  QuadraticFit<2> rows(1004, 520, 1.0 / 8);
  for (int x = 996; x <= 1012; ++x) rows.add(x, 518, field(x, 518)), rows.add(x, 520, field(x, 520));
  EXPECT_FALSE(rows.solve());
  // Points on one line x = y: u² = uv = v² along it.
  QuadraticFit<2> line(1004, 520, 1.0 / 8);
  for (int k = -8; k <= 8; ++k) line.add(1004 + k, 520 + k, field(1004 + k, 520 + k));
  EXPECT_FALSE(line.solve());
  // Fewer than six points.
  QuadraticFit<2> few(1004, 520, 1.0 / 8);
  for (int k = 0; k < 5; ++k) few.add(1000 + k, 516 + 2 * k % 5, field(1000 + k, 516 + 2 * k % 5));
  EXPECT_FALSE(few.solve());
  // A third row makes it well posed again.
  for (int x = 996; x <= 1012; x += 4) rows.add(x, 523, field(x, 523));
  EXPECT_TRUE(rows.solve());
  EXPECT_LT((rows.at(1004, 519) - field(1004, 519)).norm(), 1e-9);
}
