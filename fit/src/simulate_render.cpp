// Rendering synthetic captures: per-pixel static terms once, then per frame
// the blanching, pulse, flicker, noise and sRGB encoding (see simulate.hpp).
#include <clearfit/error.hpp>
#include <clearfit/fit/simulate.hpp>
#include <clearfit/fit/simulate_photometric.hpp>
#include <clearfit/fit/srgb.hpp>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <tbb/parallel_for.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libswscale/swscale.h>
}

#include <chrono>
#include <cmath>
#include <future>
#include <numbers>
#include <optional>
#include <random>
#include <sstream>

namespace clearfit::sim {

namespace {
constexpr double kTwoPi = 2 * std::numbers::pi;
double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}
std::uint64_t splitmix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}
/// Two doubles in one SIMD register: one division or square root for both (IEEE: the results of two scalar ones).
using Pair = double __attribute__((vector_size(16)));
Pair sqrt2(Pair a) {
#if defined(__SSE2__)
  return reinterpret_cast<Pair>(_mm_sqrt_pd(reinterpret_cast<__m128d>(a)));
#else
  return Pair{std::sqrt(a[0]), std::sqrt(a[1])};
#endif
}
/// Four floats in one SIMD register (a pixel's R, G, B and an unused lane); the square root as four scalar ones.
using Quad = float __attribute__((vector_size(16)));
using QuadI = int __attribute__((vector_size(16)));
Quad sqrt4(Quad a) {
#if defined(__SSE2__)
  return _mm_sqrt_ps(a);
#else
  return Quad{std::sqrt(a[0]), std::sqrt(a[1]), std::sqrt(a[2]), std::sqrt(a[3])};
#endif
}
constexpr int kLutSize = 65536;

/// A frame's colour terms per channel in lanes R, G, B (the fourth unused, 0): the camera's gain, the skin's e and
/// the polynomial's c1..c3 (CaptureRenderer::render); and the full well (electrons).
struct FrameColour {
  Quad gain{}, e{}, c1{}, c2{}, c3{};
  float full_well = 1;
};

/// A row's 8-bit BGR pixels `o` from its pixels' static terms (P: CaptureRenderer::Pixel), the glare (nullptr: none)
/// and the noise rows per channel, through the sRGB table: per channel poly = q0 + c1·q1 + c2·q2 + c3·q3; with glare
/// w the noise std √(σ² + gain·w / full well); lin = gain·(additive + w) + (p.gain·e)·poly + σ·noise. A pixel's three
/// channels side by side in SIMD lanes, each lane the scalar formula's float operations in its order (the same IEEE
/// results). (Four pixels side by side, transposed from their terms, measured no faster.)
template <class P>
void compose_row(const P* row, int width, const float* glare_row, const float* const noise[3], const std::uint8_t* lut,
                 const FrameColour& f, std::uint8_t* o) {
  for (int x = 0; x < width; ++x) {
    const P& p = row[x];
    const float w = glare_row ? glare_row[x] : 0.f;  // glare adds light and its shot noise
    const Quad poly = p.q[0] + f.c1 * p.q[1] + f.c2 * p.q[2] + f.c3 * p.q[3];
    Quad sigma = {p.sigma[0], p.sigma[1], p.sigma[2], 0.f};
    if (w > 0) sigma = sqrt4(sigma * sigma + f.gain * w / f.full_well);
    const Quad n = {noise[0][x], noise[1][x], noise[2][x], 0.f};
    const Quad lin = f.gain * (p.additive + w) + p.gain * f.e * poly + sigma * n;
    const QuadI idx = __builtin_convertvector(lin * float(kLutSize - 1) + 0.5f, QuadI);
    for (int c = 0; c < 3; ++c) o[3 * x + 2 - c] = lut[std::clamp(idx[c], 0, kLutSize - 1)];  // BGR
  }
}
constexpr std::size_t kNoisePool = std::size_t(1) << 22;
}  // namespace

void CameraSettings::validate() const {
  auto check = [](bool ok, const char* field, double v, const char* rule) {
    if (!ok) {
      std::ostringstream s;
      s << "CameraSettings." << field << " = " << v << ": " << rule;
      throw std::invalid_argument(s.str());
    }
  };
  check(exposure > 0 && std::isfinite(exposure), "exposure", exposure, "must be > 0");
  check(full_well_e >= 1 && std::isfinite(full_well_e), "full_well_e", full_well_e, "must be >= 1");
  check(read_noise_e >= 0 && std::isfinite(read_noise_e), "read_noise_e", read_noise_e, "must be >= 0");
  check(falloff >= 0 && falloff < 1, "falloff", falloff, "must be in [0, 1)");
  check(specular_peak >= 0 && std::isfinite(specular_peak), "specular_peak", specular_peak, "must be >= 0");
  check(specular_sigma > 0 && std::isfinite(specular_sigma), "specular_sigma", specular_sigma, "must be > 0");
  check(background >= 0 && background <= 1, "background", background, "must be in [0, 1]");
  check(flicker_amplitude >= 0 && flicker_amplitude < 1, "flicker_amplitude", flicker_amplitude, "must be in [0, 1)");
  check(flicker_hz > 0 && std::isfinite(flicker_hz), "flicker_hz", flicker_hz, "must be > 0");
  check(motion_step_px >= 0 && motion_step_px <= 5, "motion_step_px", motion_step_px, "must be in [0, 5]");
  check(motion_drift_px_per_s >= 0 && motion_drift_px_per_s <= 100, "motion_drift_px_per_s", motion_drift_px_per_s, "must be in [0, 100]");
  check(motion_tremor_px >= 0 && motion_tremor_px <= 20, "motion_tremor_px", motion_tremor_px, "must be in [0, 20]");
  check(motion_tremor_hz > 0 && motion_tremor_hz <= 100, "motion_tremor_hz", motion_tremor_hz, "must be in (0, 100]");
  check(std::abs(motion_rotation_deg) <= 10, "motion_rotation_deg", motion_rotation_deg, "must be in [-10, 10]");
  check(supersample >= 1 && supersample <= 4, "supersample", supersample, "must be 1..4");
  check(texture_mm > 0 && std::isfinite(texture_mm), "texture_mm", texture_mm, "must be > 0");
}

int Timeline::baseline_frames() const { return static_cast<int>(std::lround(baseline_s * fps)); }
int Timeline::press_frames() const { return static_cast<int>(std::lround(press_s * fps)); }
int Timeline::release_frames() const { return static_cast<int>(std::lround(release_s * fps)); }
double Timeline::press_time_s() const { return (baseline_frames() - 1) / fps; }
double Timeline::release_time_s() const { return (baseline_frames() + press_frames() - 1) / fps; }
double press_lag(const Timeline& tl, const SkinParameters& skin, double t) {
  const double tp = tl.press_time_s(), tr = tl.release_time_s();
  if (t <= tp) return 0.0;
  if (tl.release_frames() < 1 || t <= tr) return 1 - std::exp(-(t - tp) / skin.tau_on_s);
  return (1 - std::exp(-(tr - tp) / skin.tau_on_s)) * std::exp(-(t - tr) / skin.tau_off_s);
}

void BaselineGeometry::validate() const {
  if (!(std::isfinite(gap_mm) && gap_mm >= 0 && gap_mm <= 20))
    throw std::invalid_argument("baseline.gap_mm = " + std::to_string(gap_mm) + ": must be a length from 0 to 20 mm");
}

void Timeline::validate() const {
  if (!(fps > 0 && fps <= 1000)) throw std::invalid_argument("Timeline.fps must be in (0, 1000]");
  if (!(baseline_s > 0 && press_s > 0) || baseline_frames() < 1 || press_frames() < 1)
    throw std::invalid_argument("Timeline: baseline_s and press_s must give at least one frame each");
  if (crf < 0 || crf > 51) throw std::invalid_argument("Timeline.crf must be in 0..51");
  if (!(release_s >= 0 && std::isfinite(release_s))) throw std::invalid_argument("Timeline: release_s must be >= 0");
}

CaptureRenderer::CaptureRenderer(const RefractionMap& map, const ChartField& drive, const SkinParameters& skin,
                                 const CameraSettings& camera, std::uint64_t seed, const SkinDisplacement* texture_shift)
    : map_(map), skin_(skin), cam_(camera), seed_(seed), width_(map.width), height_(map.height) {
  const auto t0 = std::chrono::steady_clock::now();
  skin_.validate();
  cam_.validate();
  if (map.chart_uv.size() != static_cast<std::size_t>(width_) * height_ || map.transmittance.size() != map.chart_uv.size())
    throw std::invalid_argument("CaptureRenderer: the refraction map has no chart coordinates (trace it with a chart)");
  if (drive.value.size() != drive.grid.size() || drive.grid.size() == 0)
    throw std::invalid_argument("CaptureRenderer: empty drive field");
  // Fine skin texture over the drive's grid (plus a margin for samples at its edge).
  const ChartGrid& dg = drive.grid;
  const Vec2 lo = dg.uv_origin - Vec2::Constant(dg.texel_mm), hi = dg.uv(dg.width - 1, dg.height - 1) + Vec2::Constant(dg.texel_mm);
  double tex_mm = cam_.texture_mm;
  const double area = (hi - lo).prod();
  if (area / (tex_mm * tex_mm) > 40e6) tex_mm = std::sqrt(area / 40e6);  // at most ~40 M texels (320 MB)
  tex_grid_ = ChartGrid::covering(lo, hi, tex_mm);
  tex_mb_.resize(tex_grid_.size());
  const SkinTexture texture(skin_);
  tbb::parallel_for(0, tex_grid_.height, [&](int j) {
    for (int i = 0; i < tex_grid_.width; ++i) {
      const Vec2 uv = tex_grid_.uv(i, j);
      // Skin moved by d: the point seen at uv came from uv − d(uv).
      const float s = drive.sample(uv);
      tex_mb_[tex_grid_.index(i, j)] = {static_cast<float>(texture.modulation(texture_shift ? Vec2(uv - texture_shift->at(uv)) : uv)),
                                        static_cast<float>(steady_blood_loss(skin_, std::isfinite(s) ? s : 0.0))};
    }
  });
  // Gaussian noise pool, in deterministic chunks (each its own generator), filled in parallel.
  // Sized to the image (2^18..2^22 values): each row takes a random window of it per frame and channel.
  std::size_t pool = std::size_t(1) << 18;
  while (pool < kNoisePool && pool < static_cast<std::size_t>(width_) * height_ / 2) pool *= 2;
  noise_pool_.resize(pool);
  constexpr std::size_t kChunk = 1 << 16;
  tbb::parallel_for(std::size_t(0), pool / kChunk, [&](std::size_t c) {
    std::mt19937 rng(static_cast<std::uint32_t>(splitmix(seed ^ 0x6e6f697365ULL ^ splitmix(c))));
    std::normal_distribution<float> normal(0.f, 1.f);
    for (std::size_t k = c * kChunk; k < (c + 1) * kChunk; ++k) noise_pool_[k] = normal(rng);
  });
  srgb_lut_.resize(kLutSize);
  for (int i = 0; i < kLutSize; ++i)
    srgb_lut_[i] = static_cast<std::uint8_t>(std::lround(255 * srgb::from_linear(double(i) / (kLutSize - 1))));
  taps_.resize(map.chart_uv.size());
  for (std::size_t k = 0; k < taps_.size(); ++k) {
    const Eigen::Vector2f c = map.chart_uv[k];
    const bool chart = c.allFinite();
    taps_[k] = {chart ? c.x() : NAN, chart ? c.y() : NAN, map.transmittance[k], map.status[k] == PixelStatus::valid, false};
  }
  for (int y = 0; y + 1 < height_; ++y)
    for (int x = 0; x + 1 < width_; ++x) {
      Tap* t = &taps_[static_cast<std::size_t>(y) * width_ + x];
      bool cell = true;
      for (const Tap* o : {t, t + 1, t + width_, t + width_ + 1}) {
        const double du = double(o->u) - t->u, dv = double(o->v) - t->v;
        cell = cell && o->valid && !std::isnan(o->u) && !(du * du + dv * dv > 0.25);
      }
      t->cell = cell;
    }
  row_span_.assign(height_, {1, 0});
  for (int y = 0; y < height_; ++y)
    for (int x = 0; x < width_; ++x)
      if (map.status[map.index(x, y)] == PixelStatus::valid) {
        if (row_span_[y].first > row_span_[y].second) row_span_[y].first = x;
        row_span_[y].second = x;
      }
  pixels_.resize(static_cast<std::size_t>(width_) * height_);
  tbb::parallel_for(0, height_, [&](int y) {
    for (int x = 0; x < width_; ++x) static_pixel(x, y, pixels_[static_cast<std::size_t>(y) * width_ + x]);
  });
  for (const Pixel& p : pixels_) skin_pixels_ += p.q[0] > 0;
  setup_ms_ = ms_since(t0);
}


// The taps' bilinear read at a sub-pixel sample (sx, sy): `skin` counts the sample when its taps' weight on valid
// pixels is at least one half; false for a background sample (its weight on charted pixels under one half). Where
// a chart seam runs between the taps, the uv of the heaviest tap.
bool CaptureRenderer::read_taps(double sx, double sy, int& skin, SampleRead& out) const {
  const int x0 = static_cast<int>(std::floor(sx)), y0 = static_cast<int>(std::floor(sy));
  const double tx = sx - x0, ty = sy - y0;
  if (x0 >= 0 && y0 >= 0 && x0 + 1 < width_ && y0 + 1 < height_) {
    const Tap* t = taps_.data() + static_cast<std::size_t>(y0) * width_ + x0;
    if (t->cell) {  // four valid charted taps without a seam (most samples): the general sums below, in their order
      const Tap &t00 = t[0], &t10 = t[1], &t01 = t[width_], &t11 = t[width_ + 1];
      const double w00 = (1 - tx) * (1 - ty), w10 = tx * (1 - ty), w01 = (1 - tx) * ty, w11 = tx * ty;
      const double wsum = w00 + w10 + w01 + w11;
      skin += wsum >= 0.5;
      if (wsum < 0.5) return false;
      out = {w00 * t00.u + w10 * t10.u + w01 * t01.u + w11 * t11.u, w00 * t00.v + w10 * t10.v + w01 * t01.v + w11 * t11.v,
             w00 * t00.transmittance + w10 * t10.transmittance + w01 * t01.transmittance + w11 * t11.transmittance};
      if (wsum != 1) out = {out.u / wsum, out.v / wsum, out.transmittance / wsum};  // the weights often sum to exactly 1
      return true;
    }
  }
  double wsum = 0, tsum = 0, best_w = -1, wvalid = 0, uvx = 0, uvy = 0, best_x = 0, best_y = 0, first_x = 0, first_y = 0;
  bool seam = false, any = false;
  for (int dy = 0; dy < 2; ++dy) {
    const int y = y0 + dy;
    if (y < 0 || y >= height_) continue;
    const Tap* row = taps_.data() + static_cast<std::size_t>(y) * width_;
    for (int dx = 0; dx < 2; ++dx) {
      const int x = x0 + dx;
      if (x < 0 || x >= width_ || !row[x].valid) continue;
      const Tap& t = row[x];
      const double w = (dx ? tx : 1 - tx) * (dy ? ty : 1 - ty);
      wvalid += w;
      if (std::isnan(t.u)) continue;
      const double cx = t.u, cy = t.v;
      if (!any) first_x = cx, first_y = cy, any = true;
      else if ((cx - first_x) * (cx - first_x) + (cy - first_y) * (cy - first_y) > 0.25) seam = true;  // a chart seam between the taps
      wsum += w, uvx += w * cx, uvy += w * cy, tsum += w * t.transmittance;
      if (w > best_w) best_w = w, best_x = cx, best_y = cy;
    }
  }
  skin += wvalid >= 0.5;
  if (wsum < 0.5) return false;  // background sample
  if (seam) uvx = best_x, uvy = best_y;
  else uvx /= wsum, uvy /= wsum;
  out = {uvx, uvy, tsum / wsum};
  return true;
}

// A sample's bilinear texture read at its chart uv, added to the moments' sums Σ T·m·B^n.
void CaptureRenderer::add_texture_sample(const SampleRead& r, double acc[4]) const {
  const double fx = (r.u - tex_grid_.uv_origin.x()) / tex_grid_.texel_mm;
  const double fy = (r.v - tex_grid_.uv_origin.y()) / tex_grid_.texel_mm;
  const int i0 = std::clamp(static_cast<int>(std::floor(fx)), 0, tex_grid_.width - 2);
  const int j0 = std::clamp(static_cast<int>(std::floor(fy)), 0, tex_grid_.height - 2);
  const double u = std::clamp(fx - i0, 0.0, 1.0), v = std::clamp(fy - j0, 0.0, 1.0);
  const std::size_t k00 = tex_grid_.index(i0, j0), k01 = k00 + tex_grid_.width;
  const auto& t00 = tex_mb_[k00];
  const auto& t10 = tex_mb_[k00 + 1];
  const auto& t01 = tex_mb_[k01];
  const auto& t11 = tex_mb_[k01 + 1];
  const double m = (1 - v) * ((1 - u) * t00[0] + u * t10[0]) + v * ((1 - u) * t01[0] + u * t11[0]);
  const double B = (1 - v) * ((1 - u) * t00[1] + u * t10[1]) + v * ((1 - u) * t01[1] + u * t11[1]);
  const double tm = r.transmittance * m;
  acc[0] += tm, acc[1] += tm * B, acc[2] += tm * B * B, acc[3] += tm * B * B * B;
}

// Two samples of a row of the pixel's samples, (sx0, sy) then (sx1, sy), when both have their four taps in a flagged
// cell: read_taps' fast path and add_texture_sample's read side by side in SIMD lanes, each lane the scalar code's
// operations in its order (the same IEEE results), added to the sums sample by sample. False (nothing added) otherwise.
bool CaptureRenderer::add_cell_pair(double sx0, double sx1, double sy, double acc[4]) const {
  const int y0 = static_cast<int>(std::floor(sy)), xa = static_cast<int>(std::floor(sx0)), xb = static_cast<int>(std::floor(sx1));
  if (y0 < 0 || y0 + 1 >= height_ || xa < 0 || xb < 0 || xa + 1 >= width_ || xb + 1 >= width_) return false;
  const Tap* row = taps_.data() + static_cast<std::size_t>(y0) * width_;
  const Tap *a = row + xa, *b = row + xb;
  if (!a->cell || !b->cell) return false;
  const std::size_t w = width_;
  const double ty = sy - y0;
  const Pair tx = Pair{sx0, sx1} - Pair{double(xa), double(xb)};
  const Pair w00 = (1 - tx) * (1 - ty), w10 = tx * (1 - ty), w01 = (1 - tx) * ty, w11 = tx * ty;
  const Pair wsum = w00 + w10 + w01 + w11;  // about 1: both samples see skin
  auto taps = [&](float Tap::*f) {
    return w00 * Pair{a->*f, b->*f} + w10 * Pair{a[1].*f, b[1].*f} + w01 * Pair{a[w].*f, b[w].*f} + w11 * Pair{a[w + 1].*f, b[w + 1].*f};
  };
  Pair u = taps(&Tap::u), v = taps(&Tap::v), t = taps(&Tap::transmittance);
  if (wsum[0] != 1 || wsum[1] != 1) u /= wsum, v /= wsum, t /= wsum;  // x / 1 is x
  const Pair fx = (u - tex_grid_.uv_origin.x()) / tex_grid_.texel_mm, fy = (v - tex_grid_.uv_origin.y()) / tex_grid_.texel_mm;
  std::size_t k[2];
  Pair i0, j0;
  for (int l = 0; l < 2; ++l) {
    const int i = std::clamp(static_cast<int>(std::floor(fx[l])), 0, tex_grid_.width - 2);
    const int j = std::clamp(static_cast<int>(std::floor(fy[l])), 0, tex_grid_.height - 2);
    i0[l] = i, j0[l] = j, k[l] = tex_grid_.index(i, j);
  }
  {  // the texels the same sample reads a few pixels on (the map's chart step along its row), fetched ahead
    constexpr double kAhead = 3;
    const double px = fx[1] + kAhead * (double(a[1].u) - a->u) / tex_grid_.texel_mm, py = fy[1] + kAhead * (double(a[1].v) - a->v) / tex_grid_.texel_mm;
    if (px >= 0 && py >= 0 && px < tex_grid_.width - 1 && py < tex_grid_.height - 1) {
      const auto* ahead = &tex_mb_[tex_grid_.index(static_cast<int>(px), static_cast<int>(py))];
      __builtin_prefetch(ahead), __builtin_prefetch(ahead + tex_grid_.width);
    }
  }
  auto unit = [](Pair x) { return x < 0 ? Pair{0, 0} : Pair{1, 1} < x ? Pair{1, 1} : x; };  // std::clamp(x, 0, 1)
  const Pair tu = unit(fx - i0), tv = unit(fy - j0);
  const std::size_t tw = tex_grid_.width;
  auto texels = [&](int c) {
    const auto &a00 = tex_mb_[k[0]], &a10 = tex_mb_[k[0] + 1], &a01 = tex_mb_[k[0] + tw], &a11 = tex_mb_[k[0] + tw + 1];
    const auto &b00 = tex_mb_[k[1]], &b10 = tex_mb_[k[1] + 1], &b01 = tex_mb_[k[1] + tw], &b11 = tex_mb_[k[1] + tw + 1];
    return (1 - tv) * ((1 - tu) * Pair{a00[c], b00[c]} + tu * Pair{a10[c], b10[c]}) +
           tv * ((1 - tu) * Pair{a01[c], b01[c]} + tu * Pair{a11[c], b11[c]});
  };
  const Pair m = texels(0), B = texels(1);
  const Pair tm = t * m, tmB = tm * B, tmBB = tmB * B, tmBBB = tmBB * B;
  for (int l = 0; l < 2; ++l) acc[0] += tm[l], acc[1] += tmB[l], acc[2] += tmBB[l], acc[3] += tmBBB[l];
  return true;
}

// Moments Σ T·m·B^n / n² over the sub-pixel samples of the pixel centred at (px, py).
int CaptureRenderer::moments(double px, double py, float q[4]) const {
  const int n = cam_.supersample;
  double offset[4];  // the samples' offsets in the pixel, (a + ½)/n
  for (int a = 0; a < n; ++a) offset[a] = (a + 0.5) / n;
  double acc[4] = {0, 0, 0, 0};
  int skin = 0;
  SampleRead r;
  for (int b = 0; b < n; ++b) {
    const double sy = py + offset[b] - 0.5;
    for (int a = 0; a < n; ++a) {
      if (a + 1 < n && add_cell_pair(px + offset[a] - 0.5, px + offset[a + 1] - 0.5, sy, acc)) {
        skin += 2, ++a;
        continue;
      }
      if (read_taps(px + offset[a] - 0.5, sy, skin, r)) add_texture_sample(r, acc);  // else a background sample
    }
  }
  for (int k = 0; k < 4; ++k) q[k] = static_cast<float>(divide_by_samples(acc[k]));
  return skin;
}

void CaptureRenderer::static_pixel(double px, double py, Pixel& p, bool with_skin) const {
  p = Pixel{};
  // Skin fraction of the samples (transmittance aside), for the background share.
  const int skin = with_skin ? moments(px, py, p.q) : 0;
  const double cx = 0.5 * (width_ - 1), cy = 0.5 * (height_ - 1);
  const double sxh = cam_.specular_center.x() * width_, syh = cam_.specular_center.y() * height_, sig = cam_.specular_sigma * width_;
  // The fall-off's r² and the highlight's exponent, their two divisions in one.
  const Pair ratio = Pair{(px - cx) * (px - cx) + (py - cy) * (py - cy), (px - sxh) * (px - sxh) + (py - syh) * (py - syh)} /
                     Pair{cx * cx + cy * cy + 1e-12, 2 * sig * sig};
  const double r2 = ratio[0], spec_exponent = ratio[1];
  const double illum = cam_.exposure * (1 - cam_.falloff * r2);
  // Beyond an exponent of 60 (a factor 1e-26) the highlight adds nothing an 8-bit pixel shows.
  const double spec = cam_.specular_peak != 0 && spec_exponent < 60 ? cam_.specular_peak * std::exp(-spec_exponent) : 0.0;
  p.gain = static_cast<float>(illum);
  p.additive = static_cast<float>(illum * cam_.background * (1 - divide_by_samples(skin)) + spec);
  // The noise's std per channel: √(level·full well + read noise²) / full well, the channels' square roots and
  // divisions two at a time; no skin seen (q = 0): one level for the three channels.
  const double fw = cam_.full_well_e, read2 = cam_.read_noise_e * cam_.read_noise_e;
  double electrons[3];
  for (int c = 0; c < 3; ++c)
    electrons[c] = std::max(0.0, illum * skin_.tone.reflectance[p.q[0] == 0 ? 0 : c] * p.q[0] + p.additive) * fw + read2;
  const Pair s01 = sqrt2(Pair{electrons[0], electrons[1]}) / fw, s2 = sqrt2(Pair{electrons[2], read2}) / fw;
  p.sigma[0] = static_cast<float>(s01[0]), p.sigma[1] = static_cast<float>(s01[1]), p.sigma[2] = static_cast<float>(s2[0]);
}

void CaptureRenderer::background_pixels(int x0, int x1, double uy, double shift_x, double ca, double sa, Pixel* out) const {
  // static_pixel(q, false) of each pixel, term by term in its order: its divisions and square roots run two
  // pixels at a time (vectorised, the same IEEE results), the highlight's exponential one by one.
  const double cx = 0.5 * (width_ - 1), cy = 0.5 * (height_ - 1);
  const double sxh = cam_.specular_center.x() * width_, syh = cam_.specular_center.y() * height_, sig = cam_.specular_sigma * width_;
  const double r2_den = cx * cx + cy * cy + 1e-12, exponent_den = 2 * sig * sig;
  const int n = cam_.supersample;
  const double share = 1 - double(0) / (n * n);  // of the background: no sample sees skin
  const double fw = cam_.full_well_e, read2 = cam_.read_noise_e * cam_.read_noise_e;
  constexpr int kChunk = 256;
  alignas(16) double r2[kChunk], exponent[kChunk], electrons[kChunk + 1];
  for (int c0 = x0; c0 < x1; c0 += kChunk) {
    const int m = std::min(kChunk, x1 - c0);
    for (int i = 0; i < m; ++i) {
      const double ux = (c0 + i) - cx - shift_x;
      const double px = cx + ca * ux + sa * uy, py = cy - sa * ux + ca * uy;
      r2[i] = ((px - cx) * (px - cx) + (py - cy) * (py - cy)) / r2_den;
      exponent[i] = ((px - sxh) * (px - sxh) + (py - syh) * (py - syh)) / exponent_den;
    }
    Pixel* o = out + (c0 - x0);
    for (int i = 0; i < m; ++i) {
      Pixel& p = o[i];
      p = Pixel{};
      const double illum = cam_.exposure * (1 - cam_.falloff * r2[i]);
      const double spec = cam_.specular_peak != 0 && exponent[i] < 60 ? cam_.specular_peak * std::exp(-exponent[i]) : 0.0;
      p.gain = static_cast<float>(illum);
      p.additive = static_cast<float>(illum * cam_.background * share + spec);
      electrons[i] = std::max(0.0, illum * skin_.tone.reflectance[0] * p.q[0] + p.additive) * fw + read2;
    }
    electrons[m] = read2;
    for (int i = 0; i < m; i += 2) {
      const Pair sigma = sqrt2(Pair{electrons[i], electrons[i + 1]}) / fw;
      for (int k = 0; k < 2 && i + k < m; ++k) o[i + k].sigma[0] = o[i + k].sigma[1] = o[i + k].sigma[2] = static_cast<float>(sigma[k]);
    }
  }
}

double CaptureRenderer::linear_green(int x, int y, double t_s, double h) const {
  const Pixel& p = pixels_[static_cast<std::size_t>(y) * width_ + x];
  const double g = pulse_waveform(t_s, skin_.pulse_hz), k = skin_.absorption[1];
  const double s = h * (1 + skin_.pulse_amplitude * g);
  double poly = 0, term = 1;
  for (int n = 0; n < 4; ++n) poly += term * p.q[n], term *= k * s / (n + 1);
  return p.gain * skin_.tone.reflectance[1] * std::exp(-k * skin_.pulse_amplitude * g) * poly + p.additive;
}

cv::Mat CaptureRenderer::render(double t_s, double h, const FrameMotion& motion, std::uint64_t frame, const FrameLight* light) const {
  const Vec2& shift = motion.shift;
  cv::Mat out(height_, width_, CV_8UC3);
  const double g = pulse_waveform(t_s, skin_.pulse_hz);
  const double s = h * (1 + skin_.pulse_amplitude * g);
  const double flick = 1 + cam_.flicker_amplitude * std::sin(kTwoPi * cam_.flicker_hz * t_s);
  // The camera's gain per channel: the flicker, or the photometric schedule's (simulate_photometric.hpp).
  FrameColour f;
  for (int c = 0; c < 3; ++c) f.gain[c] = static_cast<float>(light ? light->gain[c] : flick);  // c: R, G, B
  const cv::Mat* glare = light && light->glare && !light->glare->empty() ? light->glare : nullptr;
  for (int c = 0; c < 3; ++c) {
    const double k = skin_.absorption[c], ks = k * s;
    f.e[c] = static_cast<float>(f.gain[c] * skin_.tone.reflectance[c] * std::exp(-k * skin_.pulse_amplitude * g));
    f.c1[c] = static_cast<float>(ks), f.c2[c] = static_cast<float>(ks * ks / 2), f.c3[c] = static_cast<float>(ks * ks * ks / 6);
  }
  f.full_well = static_cast<float>(cam_.full_well_e);
  const bool moved = motion.moved();
  // Rows and columns a turned pixel can reach beyond its shift.
  const double turn = std::abs(std::sin(motion.angle_rad)) * 0.5 * std::max(width_, height_);
  const double cx0 = 0.5 * (width_ - 1), cy0 = 0.5 * (height_ - 1), ca = std::cos(motion.angle_rad), sa = std::sin(motion.angle_rad);
  const std::uint64_t fseed = splitmix(seed_ ^ splitmix(frame + 1));
  tbb::parallel_for(tbb::blocked_range<int>(0, height_, 8), [&](const tbb::blocked_range<int>& rows) {
    std::vector<Pixel> moved_row(moved ? width_ : 0);
    for (int y = rows.begin(); y < rows.end(); ++y) {
      if (moved) {
        // Only pixels near the map's valid pixels of the rows the samples read can see skin.
        int lo = width_, hi = -1;
        const int yc = static_cast<int>(std::floor(y - shift.y())), reach = static_cast<int>(std::ceil(turn));
        for (int yy = std::max(0, yc - 1 - reach); yy <= std::min(height_ - 1, yc + 2 + reach); ++yy)
          if (row_span_[yy].first <= row_span_[yy].second) lo = std::min(lo, row_span_[yy].first), hi = std::max(hi, row_span_[yy].second);
        const int pad = static_cast<int>(std::ceil(std::abs(shift.x()) + turn)) + 2;
        // The still view's point seen at (x, y): q = c + R(−angle)·(p − c − shift).
        const double uy = y - cy0 - shift.y();
        const int skin_from = std::clamp(lo - pad, 0, width_), skin_to = std::clamp(hi + pad + 1, skin_from, width_);
        background_pixels(0, skin_from, uy, shift.x(), ca, sa, moved_row.data());
        for (int x = skin_from; x < skin_to; ++x) {
          const double ux = x - cx0 - shift.x();
          static_pixel(cx0 + ca * ux + sa * uy, cy0 - sa * ux + ca * uy, moved_row[x]);
        }
        background_pixels(skin_to, width_, uy, shift.x(), ca, sa, moved_row.data() + skin_to);
      }
      const Pixel* row = moved ? moved_row.data() : &pixels_[static_cast<std::size_t>(y) * width_];
      std::uint8_t* o = out.ptr<std::uint8_t>(y);
      const float* noise[3];
      for (int c = 0; c < 3; ++c)
        noise[c] = noise_pool_.data() + splitmix(fseed + 3 * static_cast<std::uint64_t>(y) + c) % (noise_pool_.size() - width_);
      compose_row(row, width_, glare ? glare->ptr<float>(y) : nullptr, noise, srgb_lut_.data(), f, o);
    }
  });
  return out;
}

VideoFormat parse_video_format(const std::string& name) {
  if (name == "ffv1") return VideoFormat::ffv1;
  if (name == "huffyuv") return VideoFormat::huffyuv;
  if (name == "mjpg") return VideoFormat::mjpg;
  if (name == "png") return VideoFormat::png;
  if (name == "h264") return VideoFormat::h264;
  throw std::invalid_argument("unknown video format '" + name + "' (ffv1, huffyuv, mjpg, png, h264)");
}
std::string to_string(VideoFormat f) {
  switch (f) {
    case VideoFormat::ffv1: return "ffv1";
    case VideoFormat::huffyuv: return "huffyuv";
    case VideoFormat::mjpg: return "mjpg";
    case VideoFormat::png: return "png";
    case VideoFormat::h264: return "h264";
  }
  return "?";
}
std::string capture_name(const std::string& stem, VideoFormat f) {
  switch (f) {
    case VideoFormat::ffv1:
    case VideoFormat::huffyuv: return stem + ".mkv";
    case VideoFormat::mjpg: return stem + ".avi";
    case VideoFormat::png: return stem;
    case VideoFormat::h264: return stem + ".mp4";
  }
  return stem;
}

struct CaptureWriter::Video {
  cv::VideoWriter writer;
};

/// A video written through FFmpeg's libraries: H.264 as a phone writes it (libx264 at a constant rate factor,
/// yuv420p, limited range, BT.709, in .mp4), or lossless HuffYUV of the RGB24 pixels in .mkv (the stream OpenCV's
/// writer made, without its swscale pass and the Matroska CRC-32 elements).
struct CaptureWriter::Libav {
  AVFormatContext* format = nullptr;
  AVCodecContext* codec = nullptr;
  AVStream* stream = nullptr;
  SwsContext* sws = nullptr;
  AVFrame* frame = nullptr;
  AVPacket* packet = nullptr;
  std::int64_t pts = 0;
  bool header = false, h264 = false;
  std::string name, codec_name;

  Libav(const std::filesystem::path& temp, const std::filesystem::path& path, VideoFormat f, double fps, cv::Size size, int crf)
      : h264(f == VideoFormat::h264), name(path.string()), codec_name(h264 ? "H.264" : "HuffYUV") {
    if (h264 && (size.width % 2 != 0 || size.height % 2 != 0)) fail("yuv420p needs an even width and height, the image is " + std::to_string(size.width) + "x" + std::to_string(size.height));
    if (h264 && (crf < 0 || crf > 51)) fail("the CRF must be 0..51, got " + std::to_string(crf));
    av_log_set_level(AV_LOG_ERROR);  // libx264 reports its statistics at the info level
    const AVCodec* enc = h264 ? avcodec_find_encoder_by_name("libx264") : avcodec_find_encoder(AV_CODEC_ID_HUFFYUV);
    if (enc == nullptr) fail(h264 ? "FFmpeg has no libx264 encoder" : "FFmpeg has no HuffYUV encoder");
    if (avformat_alloc_output_context2(&format, nullptr, h264 ? "mp4" : "matroska", temp.string().c_str()) < 0) fail("no muxer");
    stream = avformat_new_stream(format, nullptr);
    codec = avcodec_alloc_context3(enc);
    codec->width = size.width;
    codec->height = size.height;
    codec->pix_fmt = h264 ? AV_PIX_FMT_YUV420P : AV_PIX_FMT_RGB24;
    codec->framerate = av_d2q(fps, 100000);
    codec->time_base = av_inv_q(codec->framerate);
    AVDictionary* opts = nullptr;
    if (h264) set_h264(fps, crf, opts);
    if (format->oformat->flags & AVFMT_GLOBALHEADER) codec->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
    const int opened = avcodec_open2(codec, enc, &opts);
    av_dict_free(&opts);
    if (opened < 0) fail("the encoder does not open");
    avcodec_parameters_from_context(stream->codecpar, codec);
    stream->time_base = codec->time_base;
    stream->avg_frame_rate = stream->r_frame_rate = codec->framerate;
    if (avio_open(&format->pb, temp.string().c_str(), AVIO_FLAG_WRITE) < 0) fail("the file cannot be created");
    AVDictionary* muxer = nullptr;
    if (!h264) av_dict_set(&muxer, "write_crc32", "0", 0);  // a checksum over every byte written, which nothing reads
    const int written = avformat_write_header(format, &muxer);
    av_dict_free(&muxer);
    if (written < 0) fail_writing("the header cannot be written", written);
    header = true;
    frame = av_frame_alloc();
    frame->format = codec->pix_fmt;
    frame->width = size.width;
    frame->height = size.height;
    if (av_frame_get_buffer(frame, 0) < 0) fail("no memory for a frame");
    packet = av_packet_alloc();
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(name, "", "cannot write " + codec_name + ": " + what, "pick another simulation.format (png always works)");
  }
  /// A write that FFmpeg's I/O refused (`err`, an AVERROR: no space, a file size limit): the file system's reason.
  [[noreturn]] void fail_writing(const std::string& what, int err) const {
    char reason[AV_ERROR_MAX_STRING_SIZE] = {};
    av_strerror(err, reason, sizeof reason);
    throw OutputError(name, "", "cannot write " + codec_name + ": " + what + ": " + reason, "free space on its disk or give another --out");
  }
  /// libx264's settings and the BGR to YUV conversion.
  void set_h264(double fps, int crf, AVDictionary*& opts) {
    codec->gop_size = std::max(1, static_cast<int>(std::lround(fps)));
    codec->thread_count = 4;  // fixed: libx264's output depends on its thread count, and the truth must not depend on the machine
    codec->color_range = AVCOL_RANGE_MPEG;
    codec->colorspace = AVCOL_SPC_BT709;
    codec->color_primaries = AVCOL_PRI_BT709;
    codec->color_trc = AVCOL_TRC_BT709;
    av_dict_set(&opts, "crf", std::to_string(crf).c_str(), 0);
    av_dict_set(&opts, "preset", "fast", 0);
    sws = sws_getContext(codec->width, codec->height, AV_PIX_FMT_BGR24, codec->width, codec->height, AV_PIX_FMT_YUV420P,
                         SWS_BICUBIC | SWS_ACCURATE_RND | SWS_FULL_CHR_H_INP, nullptr, nullptr, nullptr);
    if (sws == nullptr) fail("no BGR to YUV conversion");
    // Full-range RGB in; BT.709 limited-range YUV out.
    sws_setColorspaceDetails(sws, sws_getCoefficients(SWS_CS_ITU709), 1, sws_getCoefficients(SWS_CS_ITU709), 0, 0, 1 << 16, 1 << 16);
  }
  ~Libav() {
    if (format != nullptr && format->pb != nullptr) avio_closep(&format->pb);
    sws_freeContext(sws);
    av_packet_free(&packet);
    av_frame_free(&frame);
    avcodec_free_context(&codec);
    avformat_free_context(format);
  }
  void drain() {
    while (avcodec_receive_packet(codec, packet) == 0) {
      if (packet->duration == 0) packet->duration = 1;  // one frame (HuffYUV leaves it unset)
      av_packet_rescale_ts(packet, codec->time_base, stream->time_base);
      packet->stream_index = stream->index;
      if (const int err = av_interleaved_write_frame(format, packet); err < 0) fail_writing("a packet cannot be written", err);
    }
  }
  void write(const cv::Mat& bgr) {
    if (av_frame_make_writable(frame) < 0) fail("no memory for a frame");
    if (sws) {
      const std::uint8_t* src[1] = {bgr.data};
      const int stride[1] = {static_cast<int>(bgr.step[0])};
      sws_scale(sws, src, stride, 0, bgr.rows, frame->data, frame->linesize);
    } else {
      for (int y = 0; y < bgr.rows; ++y) {  // BGR to RGB
        const std::uint8_t* s = bgr.ptr<std::uint8_t>(y);
        std::uint8_t* d = frame->data[0] + static_cast<std::ptrdiff_t>(y) * frame->linesize[0];
        for (int x = 0; x < bgr.cols; ++x, s += 3, d += 3) d[0] = s[2], d[1] = s[1], d[2] = s[0];
      }
    }
    frame->pts = pts++;
    if (avcodec_send_frame(codec, frame) < 0) fail("the encoder refused a frame");
    drain();
  }
  void finish() {
    avcodec_send_frame(codec, nullptr);
    drain();
    if (const int err = av_write_trailer(format); err < 0) fail_writing("the file cannot be finished", err);
    if (const int err = avio_closep(&format->pb); err < 0) fail_writing("the file cannot be closed", err);
  }
};

namespace {
/// The video packets `file` holds, demuxed (not decoded); -1 when it does not open. OpenCV's writer reports no
/// failed write (a full disk left an FFV1 file cut short and the run succeeded), so its files are counted back.
int video_packets(const std::filesystem::path& file) {
  AVFormatContext* f = nullptr;
  if (avformat_open_input(&f, file.string().c_str(), nullptr, nullptr) < 0) return -1;
  int n = -1;
  if (avformat_find_stream_info(f, nullptr) >= 0) {
    const int video = av_find_best_stream(f, AVMEDIA_TYPE_VIDEO, -1, -1, nullptr, 0);
    AVPacket* p = av_packet_alloc();
    n = 0;
    while (video >= 0 && av_read_frame(f, p) >= 0) {
      n += p->stream_index == video && !(p->flags & AV_PKT_FLAG_CORRUPT);
      av_packet_unref(p);
    }
    av_packet_free(&p);
  }
  avformat_close_input(&f);
  return n;
}
}  // namespace

CaptureWriter::CaptureWriter(const std::filesystem::path& path, VideoFormat format, double fps, cv::Size size, int crf)
    : path_(path), format_(format) {
  std::ostringstream temp_name;
  temp_name << '.' << path.filename().string() << ".tmp" << splitmix(reinterpret_cast<std::uintptr_t>(this)) % 1000000
            << (format == VideoFormat::png ? std::string() : path.extension().string());
  temp_ = path.parent_path() / temp_name.str();
  std::error_code ec;
  if (format == VideoFormat::png) {
    std::filesystem::create_directories(temp_, ec);
    if (ec) throw InputError(path.string(), "", "cannot create the frame folder: " + ec.message());
    return;
  }
  if (format == VideoFormat::h264 || format == VideoFormat::huffyuv) {
    libav_ = std::make_unique<Libav>(temp_, path, format, fps, size, crf);
    return;
  }
  const int fourcc = format == VideoFormat::ffv1 ? cv::VideoWriter::fourcc('F', 'F', 'V', '1') : cv::VideoWriter::fourcc('M', 'J', 'P', 'G');
  video_ = std::make_unique<Video>();
  const std::vector<int> params = format == VideoFormat::mjpg ? std::vector<int>{cv::VIDEOWRITER_PROP_QUALITY, 100} : std::vector<int>{};
  const int api = format == VideoFormat::mjpg ? cv::CAP_OPENCV_MJPEG : cv::CAP_FFMPEG;
  if (!video_->writer.open(temp_.string(), api, fourcc, fps, size, params))
    throw InputError(path.string(), "", "OpenCV cannot open a " + to_string(format) + " video writer for it",
                     "pick another simulation.format (png always works)");
}

CaptureWriter::~CaptureWriter() {
  if (done_) return;
  if (video_) video_->writer.release();
  libav_.reset();
  std::error_code ec;
  std::filesystem::remove_all(temp_, ec);
}

void CaptureWriter::write(const cv::Mat& frame) {
  if (format_ == VideoFormat::png) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d.png", frames_);
    if (!cv::imwrite((temp_ / name).string(), frame, {cv::IMWRITE_PNG_COMPRESSION, 1}))
      throw OutputError((path_ / name).string(), "", "cannot write the frame", "free space on its disk or give another --out");
  } else if (libav_) {
    libav_->write(frame);
  } else {
    video_->writer.write(frame);
  }
  ++frames_;
}

void CaptureWriter::finish() {
  if (video_) {
    video_->writer.release();
    if (const int n = video_packets(temp_); n != frames_)
      throw OutputError(path_.string(), "", "the video holds " + std::to_string(std::max(n, 0)) + " of its " + std::to_string(frames_) +
                       " frames: a write failed (no space, a file size limit)", "free space on its disk or give another --out");
  }
  if (libav_) libav_->finish(), libav_.reset();
  std::error_code ec;
  if (std::filesystem::exists(path_)) std::filesystem::remove_all(path_, ec);
  std::filesystem::rename(temp_, path_, ec);
  if (ec) throw InputError(path_.string(), "", "cannot move the capture into place: " + ec.message());
  done_ = true;
}

CaptureSummary render_captures(const CaptureRenderer& r, const SkinParameters& skin, const Timeline& tl,
                               const CameraSettings& cam, VideoFormat format, const std::filesystem::path& dir,
                               std::uint64_t seed, const std::function<void(int, int)>& progress,
                               const PhotometricSchedule* photometry, const CaptureRenderer* baseline) {
  tl.validate();
  if (baseline && (baseline->width() != r.width() || baseline->height() != r.height()))
    throw std::invalid_argument("render_captures: the baseline renderer's image differs from the worn one's");
  CaptureSummary sum;
  sum.baseline_frames = tl.baseline_frames();
  sum.press_frames = tl.press_frames();
  sum.release_frames = tl.release_frames();
  const int total = sum.baseline_frames + sum.press_frames + sum.release_frames;
  sum.press_start_frame = tl.single_video ? sum.baseline_frames : 0;
  std::mt19937_64 rng(splitmix(seed ^ 0x6d6f74696f6eULL));
  std::normal_distribution<double> step(0, cam.motion_step_px);
  // Drift and tremor directions and the tremor's phase, from the seed (drawn after the walk's steps).
  std::mt19937_64 dir_rng(splitmix(seed ^ 0x647269667400ULL));
  std::uniform_real_distribution<double> turn(0, kTwoPi);
  const double drift_dir = turn(dir_rng), tremor_dir = turn(dir_rng), tremor_phase = turn(dir_rng);
  const Vec2 drift = cam.motion_drift_px_per_s * Vec2(std::cos(drift_dir), std::sin(drift_dir));
  const Vec2 tremor = cam.motion_tremor_px * Vec2(std::cos(tremor_dir), std::sin(tremor_dir));
  Vec2 walk = Vec2::Zero();
  for (int k = 0; k < total; ++k) {
    if (k > 0 && cam.motion_step_px > 0) walk += Vec2(step(rng), step(rng));
    const double t = k / tl.fps;
    // Tremor measured from its value at the first frame, so the first frame is the reference.
    const double shake = std::sin(kTwoPi * cam.motion_tremor_hz * t + tremor_phase) - std::sin(tremor_phase);
    sum.shift_px.push_back(walk + drift * t + tremor * shake);
    sum.angle_rad.push_back(total > 1 ? cam.motion_rotation_deg * std::numbers::pi / 180 * k / (total - 1) : 0.0);
  }
  const cv::Size size(r.width(), r.height());
  std::vector<std::unique_ptr<CaptureWriter>> writers;
  if (tl.single_video) {
    sum.files = {capture_name("capture", format)};
  } else {
    sum.files = {capture_name("baseline", format), capture_name("worn", format)};
  }
  for (const auto& f : sum.files) writers.push_back(std::make_unique<CaptureWriter>(dir / f, format, tl.fps, size, tl.crf));
  std::future<void> pending;
  for (int k = 0; k < total; ++k) {
    const double t = k / tl.fps;
    const double h = press_lag(tl, skin, t);
    auto t0 = std::chrono::steady_clock::now();
    const std::optional<FrameLight> light = photometry ? std::optional(photometry->frame(k)) : std::nullopt;
    // Not worn: before the press, and after the part's removal.
    const bool worn = k >= sum.baseline_frames && k < sum.baseline_frames + sum.press_frames;
    const CaptureRenderer& through = baseline && !worn ? *baseline : r;
    cv::Mat frame = through.render(t, h, FrameMotion(sum.shift_px[k], sum.angle_rad[k]), static_cast<std::uint64_t>(k), light ? &*light : nullptr);
    sum.render_ms += ms_since(t0);
    t0 = std::chrono::steady_clock::now();
    if (pending.valid()) pending.get();
    sum.write_ms += ms_since(t0);
    CaptureWriter* w = writers[tl.single_video || k < sum.baseline_frames ? 0 : 1].get();
    pending = std::async(std::launch::async, [w, f = std::move(frame)] { w->write(f); });
    if (progress) progress(k + 1, total);
  }
  const auto t0 = std::chrono::steady_clock::now();
  if (pending.valid()) pending.get();
  for (auto& w : writers) w->finish();
  sum.write_ms += ms_since(t0);
  return sum;
}

}  // namespace clearfit::sim
