// B-spline interpolation with its gradient (see spline_sampler.hpp).
#include "spline_sampler.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace clearfit {

namespace {

constexpr int kTableIntervals = 1024;  ///< SplineSampler::table_'s nodes per unit of t

/// Poles of the prefilter: the roots inside the unit circle of the sampled B-spline's z-transform
/// (cubic: z² + 4z + 1; quintic: z⁴ + 26z³ + 66z² + 26z + 1).
std::vector<double> poles(int order) {
  if (order == 3) return {std::sqrt(3.0) - 2};
  return {-0.43057534709997379, -0.043096288203264653};
}

/// One pole's causal and anticausal recursion along `n` values spaced `stride` apart, on `lanes` such sequences
/// side by side (value k of lane x at c[k·stride + x]), with its gain (1 − z)(1 − 1/z) and mirror boundaries
/// (Unser 1999, box 2): the causal start sums the mirrored sequence until the pole's powers fall below 1e-7; the
/// anticausal start is the closed form for a mirrored end. A single value is its own coefficient. Each lane gets
/// the same operations in the same order; the lanes make a column pass walk memory row by row (one column at a
/// time it strided through memory and cost 9 % of the bundled sample's assessment). `sum`: scratch.
void recurse(float* c, int n, std::ptrdiff_t stride, int lanes, double z, std::vector<double>& sum) {
  if (n < 2) return;
  const double gain = (1 - z) * (1 - 1 / z);
  auto at = [&](int k) { return c + k * stride; };
  for (int k = 0; k < n; ++k)
    for (float *r = at(k), *e = r + lanes; r < e; ++r) *r = static_cast<float>(gain * *r);
  const int horizon = std::min(n, static_cast<int>(std::ceil(std::log(1e-7) / std::log(std::abs(z)))));
  sum.assign(at(0), at(0) + lanes);
  double zk = z;
  for (int k = 1; k < horizon; ++k, zk *= z)
    for (int x = 0; x < lanes; ++x) sum[x] += zk * at(k)[x];
  for (int x = 0; x < lanes; ++x) at(0)[x] = static_cast<float>(sum[x]);
  for (int k = 1; k < n; ++k)
    for (float *r = at(k), *p = at(k - 1), *e = r + lanes; r < e; ++r, ++p) *r = static_cast<float>(*r + z * *p);
  for (float *last = at(n - 1), *before = at(n - 2), *e = last + lanes; last < e; ++last, ++before)
    *last = static_cast<float>(z / (z * z - 1) * (*last + z * *before));
  for (int k = n - 2; k >= 0; --k)
    for (float *r = at(k), *next = at(k + 1), *e = r + lanes; r < e; ++r, ++next) *r = static_cast<float>(z * (*next - *r));
}

/// (x)₊ to the power p.
inline float pos_pow(float x, int p) {
  if (x <= 0) return 0;
  float r = x;
  for (int i = 1; i < p; ++i) r *= x;
  return r;
}

}  // namespace

SplineSampler::SplineSampler(int order) : order_(order) {
  if (order != 3 && order != 5) throw std::invalid_argument("SplineSampler: the order must be 3 or 5");
  auto build = [this] {
    const int taps = order_ + 1;
    std::vector<float> t(static_cast<std::size_t>(kTableIntervals + 1) * 2 * taps);
    for (int i = 0; i <= kTableIntervals; ++i) {
      float* node = &t[static_cast<std::size_t>(i) * 2 * taps];
      weights(static_cast<float>(i) / kTableIntervals, node, node + taps);
    }
    return t;
  };
  if (order == 3) {
    static const std::vector<float> cubic = build();
    table_ = &cubic;
  } else {
    static const std::vector<float> quintic = build();
    table_ = &quintic;
  }
}


void SplineSampler::coefficients(cv::Mat& m) const {
  CV_Assert(m.type() == CV_32F && m.isContinuous());
  float* d = m.ptr<float>();
  std::vector<double> sum;
  for (double z : poles(order_)) {
    for (int y = 0; y < m.rows; ++y) recurse(d + static_cast<std::ptrdiff_t>(y) * m.cols, m.cols, 1, 1, z, sum);
    recurse(d, m.rows, m.cols, m.cols, z, sum);  // the columns, side by side
  }
}

namespace {
/// x⁵ and x⁴, multiplied in the order pos_pow does.
inline float p5(float x) { return (((x * x) * x) * x) * x; }
inline float p4(float x) { return ((x * x) * x) * x; }
}  // namespace

void SplineSampler::weights(float t, float* w, float* dw) const {
  // Tap j sits at floor(x) − before() + j, at distance u = t + before() − j from x.
  if (order_ == 3) {
    for (int j = 0; j <= 3; ++j) {
      const float u = t + static_cast<float>(1 - j), a = std::abs(u), s = u < 0 ? -1.f : 1.f;
      w[j] = (pos_pow(2 - a, 3) - 4 * pos_pow(1 - a, 3)) / 6;
      if (dw) dw[j] = -s * (pos_pow(2 - a, 2) - 4 * pos_pow(1 - a, 2)) / 2;
    }
    return;
  }
  // For t in [0, 1) each tap's |u| lies in a known unit interval: the terms (k − |u|)₊ that vanish there are
  // left out (a zero term adds nothing: the values are the general form's).
  float a[6];
  for (int j = 0; j < 6; ++j) a[j] = std::abs(t + static_cast<float>(2 - j));
  const float t0 = 3 - a[0], t1 = 3 - a[1], u1 = 2 - a[1], t2 = 3 - a[2], u2 = 2 - a[2], v2 = 1 - a[2];
  const float t3 = 3 - a[3], u3 = 2 - a[3], v3 = 1 - a[3], t4 = 3 - a[4], u4 = 2 - a[4], t5 = 3 - a[5];
  w[0] = p5(t0) / 120;
  w[1] = (p5(t1) - 6 * p5(u1)) / 120;
  w[2] = (p5(t2) - 6 * p5(u2) + 15 * p5(v2)) / 120;
  w[3] = (p5(t3) - 6 * p5(u3) + 15 * p5(v3)) / 120;
  w[4] = (p5(t4) - 6 * p5(u4)) / 120;
  w[5] = p5(t5) / 120;
  if (!dw) return;
  dw[0] = -(p4(t0)) / 24;
  dw[1] = -(p4(t1) - 6 * p4(u1)) / 24;
  dw[2] = -(p4(t2) - 6 * p4(u2) + 15 * p4(v2)) / 24;
  dw[3] = (p4(t3) - 6 * p4(u3) + 15 * p4(v3)) / 24;
  dw[4] = (p4(t4) - 6 * p4(u4)) / 24;
  dw[5] = p4(t5) / 24;
}

namespace {
/// SplineSampler::sample at each position (bx + dx, by + dy) on its own, with `Taps` taps per axis (known at compile
/// time, so the tap loops unroll) and the weights interpolated linearly in `table` (SplineSampler::table_).
template <int Taps>
bool sample_each(const std::vector<float>& table, const cv::Mat& coef, const cv::Mat& bx, const cv::Mat& by, double dx, double dy,
                 cv::Mat& out, cv::Mat* gx, cv::Mat* gy) {
  constexpr int b = (Taps - 1) / 2, n = kTableIntervals;  // b: SplineSampler::before()
  static_assert(Taps == 4 || Taps == 6);
  const bool value_only = !gx && !gy;
  auto lookup = [&](float t, float* w, float* dw) {
    const float f = std::clamp(t, 0.f, 1.f) * n;
    const int i = std::min(static_cast<int>(f), n - 1);
    const float r = f - static_cast<float>(i);
    const float* lo = &table[static_cast<std::size_t>(i) * 2 * Taps];
    const float* hi = lo + 2 * Taps;
    for (int j = 0; j < Taps; ++j) w[j] = lo[j] + r * (hi[j] - lo[j]);
    if (!value_only)
      for (int j = 0; j < Taps; ++j) dw[j] = lo[Taps + j] + r * (hi[Taps + j] - lo[Taps + j]);
  };
  float wx[Taps]{}, wy[Taps]{}, dwx[Taps]{}, dwy[Taps]{};
  for (int j = 0; j < bx.rows; ++j) {
    const float *px = bx.ptr<float>(j), *py = by.ptr<float>(j);
    float* o = out.ptr<float>(j);
    float* ox = gx ? gx->ptr<float>(j) : nullptr;
    float* oy = gy ? gy->ptr<float>(j) : nullptr;
    for (int i = 0; i < bx.cols; ++i) {
      const double x = px[i] + dx, y = py[i] + dy;
      const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
      if (x0 - b < 0 || y0 - b < 0 || x0 - b + Taps > coef.cols || y0 - b + Taps > coef.rows) return false;
      lookup(static_cast<float>(x - x0), wx, dwx);
      lookup(static_cast<float>(y - y0), wy, dwy);
      float v = 0, vx = 0, vy = 0;
      if (value_only) {  // the value alone (the fit's samples): the same sums without the gradient's
        for (int r = 0; r < Taps; ++r) {
          const float* row = coef.ptr<float>(y0 - b + r) + (x0 - b);
          float s = 0;
          for (int a = 0; a < Taps; ++a) s += wx[a] * row[a];
          v += wy[r] * s;
        }
        o[i] = v;
        continue;
      }
      for (int r = 0; r < Taps; ++r) {
        const float* row = coef.ptr<float>(y0 - b + r) + (x0 - b);
        float s = 0, sx = 0;
        for (int a = 0; a < Taps; ++a) s += wx[a] * row[a], sx += dwx[a] * row[a];
        v += wy[r] * s, vx += wy[r] * sx, vy += dwy[r] * s;
      }
      o[i] = v;
      if (ox) ox[i] = vx;
      if (oy) oy[i] = vy;
    }
  }
  return true;
}
}  // namespace

bool SplineSampler::sample(const cv::Mat& coef, const cv::Mat& bx, const cv::Mat& by, double dx, double dy, bool uniform,
                           cv::Mat& out, cv::Mat* gx, cv::Mat* gy) const {
  const int taps = order_ + 1, b = before();
  float wx[6], wy[6], dwx[6], dwy[6];
  auto outside = [&](int x0, int y0, int w, int h) { return x0 - b < 0 || y0 - b < 0 || x0 + w - 1 + after() >= coef.cols || y0 + h - 1 + after() >= coef.rows; };
  if (uniform) {
    const double x = bx.at<float>(0, 0) + dx, y = by.at<float>(0, 0) + dy;
    const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
    if (outside(x0, y0, bx.cols, bx.rows)) return false;
    weights(static_cast<float>(x - x0), wx, dwx);
    weights(static_cast<float>(y - y0), wy, dwy);
    const cv::Mat src = coef(cv::Rect(x0 - b, y0 - b, bx.cols + taps - 1, bx.rows + taps - 1));
    const cv::Rect in(0, 0, bx.cols, bx.rows);
    auto filter = [&](float* kx, float* ky, cv::Mat& dst) {
      cv::Mat f;
      cv::sepFilter2D(src, f, CV_32F, cv::Mat(1, taps, CV_32F, kx), cv::Mat(taps, 1, CV_32F, ky), cv::Point(0, 0), 0, cv::BORDER_REPLICATE);
      dst = f(in);
    };
    filter(wx, wy, out);
    if (gx) filter(dwx, wy, *gx);
    if (gy) filter(wx, dwy, *gy);
    return true;
  }
  out.create(bx.size(), CV_32F);
  if (gx) gx->create(bx.size(), CV_32F);
  if (gy) gy->create(bx.size(), CV_32F);
  if (order_ == 3) return sample_each<4>(*table_, coef, bx, by, dx, dy, out, gx, gy);
  return sample_each<6>(*table_, coef, bx, by, dx, dy, out, gx, gy);
}

void SplineSampler::gradient(const cv::Mat& coef, cv::Mat& gx, cv::Mat& gy) const {
  const int taps = order_ + 1;
  float w[6], dw[6];
  weights(0, w, dw);
  const cv::Point anchor(before(), before());
  cv::sepFilter2D(coef, gx, CV_32F, cv::Mat(1, taps, CV_32F, dw), cv::Mat(taps, 1, CV_32F, w), anchor, 0, cv::BORDER_REFLECT_101);
  cv::sepFilter2D(coef, gy, CV_32F, cv::Mat(1, taps, CV_32F, w), cv::Mat(taps, 1, CV_32F, dw), anchor, 0, cv::BORDER_REFLECT_101);
}

}  // namespace clearfit
