// Hotspots against hand-computed cases: nested thresholds give one place with
// its area at each level (closed forms of a Gaussian), ids and label image
// agree, unseen texels between two pressed parts join them as unseen (not as
// 0), the centroid lies on a curved surface while the 3D mean lies inside, and the centres' σ match their
// scatter over noise realisations (a gated field's too), and a model's residual moves a place's mean and area as
// raising the field by it does.
#include <clearfit/fit/hotspots.hpp>
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/shapes.hpp>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <functional>
#include <numbers>

#include "../support/trace_part.hpp"

namespace clearfit {
namespace {

constexpr double kPi = std::numbers::pi;

struct Flat {
  test::TracePart part{shapes::slab(20, 20, 2, 8)};
  Chart chart = compute_chart(part.mesh, part.contact);
  ChartGrid grid = ChartGrid::covering(chart.uv_min, chart.uv_max, 0.02);
  ChartRaster raster = rasterize_chart(part.mesh, chart, grid);
  Vec2 centre = 0.5 * (chart.uv_min + chart.uv_max);
  ChartField field(const std::function<double(double dx, double dy)>& f) const {
    ChartField out{grid, std::vector<float>(grid.size(), NAN)};
    for (int j = 0; j < grid.height; ++j)
      for (int i = 0; i < grid.width; ++i)
        if (raster.face[grid.index(i, j)] >= 0) {
          const Vec2 d = grid.uv(i, j) - centre;
          out.value[grid.index(i, j)] = static_cast<float>(f(d.x(), d.y()));
        }
    return out;
  }
};

TEST(Hotspots, NestedThresholdsGiveOnePlaceWithItsAreaAtEachLevel) {
  const Flat f;
  const double peak = 12, s = 1.5;
  // Two Gaussians 8 mm apart: two places, each listed once.
  const ChartField p = f.field([&](double x, double y) {
    return peak * std::exp(-((x + 4) * (x + 4) + y * y) / (2 * s * s)) + 0.6 * peak * std::exp(-((x - 4) * (x - 4) + y * y) / (2 * s * s));
  });
  ChartField sigma{f.grid, std::vector<float>(f.grid.size(), 0.2f)};
  HotspotOptions o;
  o.thresholds = {5.5, 4.3};  // any order: they nest
  std::vector<int> labels;
  const auto hs = find_hotspots(p, &sigma, nullptr, f.raster, o, &labels, &f.part.mesh);
  ASSERT_EQ(hs.size(), 2u);
  for (int k = 0; k < 2; ++k) {
    const Hotspot& h = hs[k];
    const double top = k == 0 ? peak : 0.6 * peak;
    EXPECT_EQ(h.id, k + 1);
    EXPECT_NEAR(h.peak, top, 0.01);
    ASSERT_EQ(h.levels.size(), 2u);
    for (int l = 0; l < 2; ++l) {
      const double t = l == 0 ? 4.3 : 5.5;
      EXPECT_EQ(h.levels[l].threshold, t);
      // Area where top·exp(−r²/2s²) ≥ t: 2πs²·ln(top/t). Its σ: the outline (radius r, |∇p| = t r / s²) moves by
      // 0.2 / |∇p|, the noise shared along it over ℓ = 1 mm (samples_per_mm2 1): variance 2πr · 0.2² ℓ / |∇p|².
      EXPECT_NEAR(h.levels[l].area_mm2, 2 * kPi * s * s * std::log(top / t), 0.05) << k << " " << l;
      const double r = s * std::sqrt(2 * std::log(top / t)), grad = t * r / (s * s);
      EXPECT_NEAR(h.levels[l].area_sigma_mm2, std::sqrt(2 * kPi * r * 0.2 * 0.2 / (grad * grad)), 0.02) << k << " " << l;
      EXPECT_NEAR(h.levels[l].mean, (top - t) / std::log(top / t), 0.02);
    }
    EXPECT_EQ(h.area_mm2, h.levels[0].area_mm2);
    EXPECT_NEAR(h.centroid_mm.x(), k == 0 ? -4 : 4, 0.01);
    EXPECT_EQ(h.unseen_area_mm2, 0.0);
    // The label image carries the same id over the place's lowest level.
    long long n = 0;
    for (int id : labels) n += id == h.id;
    EXPECT_EQ(n, h.levels[0].texels);
  }
}

TEST(Hotspots, UnseenTexelsBetweenPressedPartsJoinThemAsUnseen) {
  const Flat f;
  // A pressed disk (r < 1.5), an unseen ring (1.5..2.3), a pressed ring (2.3..2.8), as a bump's face, wall and plate.
  const ChartField p = f.field([](double x, double y) {
    const double r = std::hypot(x, y);
    return r < 1.5 ? 10.0 : r < 2.3 ? NAN : r < 2.8 ? 8.0 : 0.0;
  });
  HotspotOptions o;
  o.thresholds = {4.3};
  const auto joined = find_hotspots(p, nullptr, nullptr, f.raster, o);
  ASSERT_EQ(joined.size(), 1u);
  EXPECT_NEAR(joined[0].area_mm2, kPi * (1.5 * 1.5 + 2.8 * 2.8 - 2.3 * 2.3), 0.1);
  EXPECT_NEAR(joined[0].unseen_area_mm2, kPi * (2.3 * 2.3 - 1.5 * 1.5), 0.1);  // counted as unseen, not as 0 kPa
  EXPECT_NEAR(joined[0].mean, (10 * 1.5 * 1.5 + 8 * (2.8 * 2.8 - 2.3 * 2.3)) / (1.5 * 1.5 + 2.8 * 2.8 - 2.3 * 2.3), 0.05);
  o.unseen_reach_mm = 0.3;  // too short to cross the 0.8 mm ring: two places, each with unseen skin beside it
  const auto apart = find_hotspots(p, nullptr, nullptr, f.raster, o);
  ASSERT_EQ(apart.size(), 2u);
  EXPECT_GT(apart[0].unseen_area_mm2, 0.5);
  EXPECT_GT(apart[1].unseen_area_mm2, 0.5);
}

TEST(Hotspots, CentroidLiesOnACurvedSurfaceAndTheMeanInside) {
  const double r_in = 10;
  test::TracePart part(shapes::cylindrical_shell(r_in, 12, 120, 10, 96, 10));
  const Chart chart = compute_chart(part.mesh, part.contact);
  const ChartGrid grid = ChartGrid::covering(chart.uv_min, chart.uv_max, 0.05);
  const ChartRaster raster = rasterize_chart(part.mesh, chart, grid);
  const Vec2 centre = 0.5 * (chart.uv_min + chart.uv_max);
  ChartField p{grid, std::vector<float>(grid.size(), NAN)};
  for (int j = 0; j < grid.height; ++j)
    for (int i = 0; i < grid.width; ++i)
      if (raster.face[grid.index(i, j)] >= 0)
        p.value[grid.index(i, j)] = static_cast<float>(10 * std::exp(-(grid.uv(i, j) - centre).squaredNorm() / (2 * 3.0 * 3.0)));
  HotspotOptions o;
  o.thresholds = {4.3};
  const auto hs = find_hotspots(p, nullptr, nullptr, raster, o, nullptr, &part.mesh);
  ASSERT_EQ(hs.size(), 1u);
  auto radius = [](const Vec3& v) { return std::hypot(v.x(), v.z()); };  // the shell's axis is y
  std::printf("centroid at radius %.4f, 3D mean at %.4f (inner surface %.1f)\n", radius(hs[0].centroid_mm), radius(hs[0].centroid_mean_mm), r_in);
  EXPECT_LT(radius(hs[0].centroid_mean_mm), r_in - 0.05);  // a curved region's mean lies inside the skin
  // On the faceted surface: within the facets' sagitta r(1 − cos(π/96 · 120/360)) of the circle.
  EXPECT_NEAR(radius(hs[0].centroid_mm), r_in, r_in * (1 - std::cos(kPi * 120 / 360 / 96)) + 1e-9);
  EXPECT_NEAR((hs[0].centroid_mm - hs[0].centroid_mean_mm).norm(), r_in - radius(hs[0].centroid_mean_mm), 0.01);
}

/// A Gaussian place plus noise smoothed like the assessment's signal (white per texel, then a Gaussian of σ_s),
/// on a slab: realisations of it, optionally gated as a lossy capture's pressure is (values under `gate` read 0).
struct NoisyPlace {
  test::TracePart part{shapes::slab(10, 10, 2, 4)};
  Chart chart = compute_chart(part.mesh, part.contact);
  ChartGrid grid = ChartGrid::covering(chart.uv_min, chart.uv_max, 0.05);
  ChartRaster raster = rasterize_chart(part.mesh, chart, grid);
  double peak = 10, width = 1.2, noise = 0.3, smooth_mm = 0.25;
  ChartField clean{grid, std::vector<float>(grid.size(), NAN)};
  ChartField sigma{grid, std::vector<float>(grid.size(), static_cast<float>(noise))};
  NoisyPlace() {
    const Vec2 centre = 0.5 * (chart.uv_min + chart.uv_max);
    for (int j = 0; j < grid.height; ++j)
      for (int i = 0; i < grid.width; ++i)
        if (raster.face[grid.index(i, j)] >= 0)
          clean.value[grid.index(i, j)] = static_cast<float>(peak * std::exp(-(grid.uv(i, j) - centre).squaredNorm() / (2 * width * width)));
  }
  HotspotOptions options(double threshold) const {
    HotspotOptions o;
    o.thresholds = {threshold};
    o.samples_per_mm2 = 1.0 / (4 * kPi * smooth_mm * smooth_mm);
    return o;
  }
  ChartField realise(cv::RNG& rng, double gate = -INFINITY) const {
    const double smooth_px = smooth_mm / grid.texel_mm;
    const cv::Mat k1 = cv::getGaussianKernel(2 * static_cast<int>(std::ceil(4 * smooth_px)) + 1, smooth_px, CV_64F);
    const double gain = k1.dot(k1);  // variance of white unit noise after the 2D (separable) kernel: (Σ k²)²
    cv::Mat white(grid.height, grid.width, CV_64F), smoothed;
    rng.fill(white, cv::RNG::NORMAL, 0.0, noise / gain);
    cv::GaussianBlur(white, smoothed, cv::Size(), smooth_px, smooth_px, cv::BORDER_REFLECT);
    ChartField f = clean;
    for (int j = 0; j < grid.height; ++j)
      for (int i = 0; i < grid.width; ++i) {
        float& v = f.value[grid.index(i, j)];
        v += static_cast<float>(smoothed.at<double>(j, i));
        if (v < gate) v = 0.f;
      }
    return f;
  }
};

TEST(Hotspots, CentreOfPressureAndCentroidSigmasMatchTheScatterOverNoiseRealisations) {
  // The centre of pressure's and the centroid's rms scatter over realisations against their propagated σ.
  // The centroid moves only with the outline, so it is the check of the outline's term.
  const NoisyPlace place;
  const HotspotOptions o = place.options(3.0);  // 10 σ of the noise: the place's outline hardly moves (the propagation is for a given place)
  const auto truth = find_hotspots(place.clean, &place.sigma, nullptr, place.raster, o, nullptr, &place.part.mesh);
  ASSERT_EQ(truth.size(), 1u);
  cv::RNG rng(7);
  double sum_d2 = 0, sum_predicted = 0, sum_c2 = 0, sum_c_predicted = 0, sum_a2 = 0, sum_a_predicted = 0;
  const int runs = 200;
  for (int r = 0; r < runs; ++r) {
    const auto hs = find_hotspots(place.realise(rng), &place.sigma, nullptr, place.raster, o, nullptr, &place.part.mesh);
    ASSERT_GE(hs.size(), 1u);
    sum_d2 += (hs[0].centre_of_pressure_mm - truth[0].centre_of_pressure_mm).squaredNorm();
    sum_predicted += hs[0].centre_of_pressure_sigma_mm;
    sum_c2 += (hs[0].centroid_mm - truth[0].centroid_mm).squaredNorm();
    sum_c_predicted += hs[0].centroid_sigma_mm;
    sum_a2 += (hs[0].area_mm2 - truth[0].area_mm2) * (hs[0].area_mm2 - truth[0].area_mm2);
    sum_a_predicted += hs[0].levels[0].area_sigma_mm2;
  }
  const double measured = std::sqrt(sum_d2 / runs), predicted = sum_predicted / runs;
  std::printf("centre of pressure: rms scatter %.4f mm over %d realisations, propagated sigma %.4f mm\n", measured, runs, predicted);
  EXPECT_NEAR(predicted, measured, 0.15 * measured);
  const double c_measured = std::sqrt(sum_c2 / runs), c_predicted = sum_c_predicted / runs;
  std::printf("centroid: rms scatter %.4f mm, propagated sigma %.4f mm\n", c_measured, c_predicted);
  EXPECT_NEAR(c_predicted, c_measured, 0.2 * c_measured);
  // The area moves with the same outline (its noise shared along it over the correlation length); half the band
  // within ±σ of the threshold, as it was, gave several times the scatter.
  const double a_measured = std::sqrt(sum_a2 / runs), a_predicted = sum_a_predicted / runs;
  std::printf("area: rms scatter %.4f mm2, propagated sigma %.4f mm2\n", a_measured, a_predicted);
  EXPECT_NEAR(a_predicted, a_measured, 0.25 * a_measured);
  // Without a sigma field there is no σ.
  const Hotspot without = find_hotspots(place.clean, nullptr, nullptr, place.raster, o, nullptr, &place.part.mesh)[0];
  EXPECT_TRUE(std::isnan(without.centre_of_pressure_sigma_mm));
  EXPECT_TRUE(std::isnan(without.centroid_sigma_mm));
}

TEST(Hotspots, CentreOfPressureOfAGatedFieldWeighsItAboveItsOutline) {
  // A lossy capture's pressure is 0 under its detection gate's tail: a place's outline is a step from 0 to the tail,
  // above the threshold, where the place's slope is low and the noise moves it most. Weighted by the field above the
  // outline level (HotspotOptions::outline_level) the texels it moves weigh 0: the scatter against the propagated
  // σ, and against the scatter weighted above the threshold alone.
  const NoisyPlace place;
  const double threshold = 1.0, tail = 2.0;  // the tail at a fifth of the peak: σ/|∇v| 0.1 mm of outline motion
  HotspotOptions o = place.options(threshold), at_threshold = o;
  o.outline_level = tail;
  const auto truth = find_hotspots(place.clean, &place.sigma, nullptr, place.raster, o, nullptr, &place.part.mesh);
  ASSERT_EQ(truth.size(), 1u);
  cv::RNG rng(11);
  double sum_d2 = 0, sum_predicted = 0, sum_t2 = 0;
  const int runs = 200;
  for (int r = 0; r < runs; ++r) {
    const ChartField f = place.realise(rng, tail);
    const auto hs = find_hotspots(f, &place.sigma, nullptr, place.raster, o, nullptr, &place.part.mesh);
    const auto ht = find_hotspots(f, &place.sigma, nullptr, place.raster, at_threshold, nullptr, &place.part.mesh);
    ASSERT_EQ(hs.size(), 1u);
    ASSERT_EQ(ht.size(), 1u);
    sum_d2 += (hs[0].centre_of_pressure_mm - truth[0].centre_of_pressure_mm).squaredNorm();
    sum_predicted += hs[0].centre_of_pressure_sigma_mm;
    sum_t2 += (ht[0].centre_of_pressure_mm - truth[0].centre_of_pressure_mm).squaredNorm();
  }
  const double measured = std::sqrt(sum_d2 / runs), predicted = sum_predicted / runs, at_t = std::sqrt(sum_t2 / runs);
  std::printf("gated at %.1f: centre of pressure's rms scatter %.4f mm, propagated sigma %.4f mm; weighted above the threshold %.1f "
              "instead: %.4f mm\n",
              tail, measured, predicted, threshold, at_t);
  EXPECT_NEAR(predicted, measured, 0.15 * measured);
  EXPECT_LT(measured, at_t);
}

TEST(Hotspots, APlaceOfSaturatedTexelsHasNoSigmaRatherThanZero) {
  // A speck read at the calibration's saturation (its texels' σ unknown: lower bounds) beside texels far under the
  // threshold (a lossy capture's gate): nothing propagates a σ to its centres, which must then be unknown (NaN, null
  // in the report), not 0 (seen at 640×360 CRF 28: "centre of pressure ± 0.00 mm").
  const NoisyPlace place;
  ChartField f = place.clean, s = place.sigma;
  const Vec2 centre = 0.5 * (place.chart.uv_min + place.chart.uv_max);
  for (int j = 0; j < place.grid.height; ++j)
    for (int i = 0; i < place.grid.width; ++i) {
      const auto k = place.grid.index(i, j);
      if (!std::isfinite(f.value[k])) continue;
      const bool in = (place.grid.uv(i, j) - centre).norm() < 0.5;
      f.value[k] = in ? 13.7f : 0.f;
      s.value[k] = in ? NAN : 0.3f;
    }
  const auto hs = find_hotspots(f, &s, nullptr, place.raster, place.options(4.3), nullptr, &place.part.mesh);
  ASSERT_EQ(hs.size(), 1u);
  EXPECT_NEAR(hs[0].area_mm2, kPi * 0.25, 0.1);
  EXPECT_TRUE(std::isnan(hs[0].centre_of_pressure_sigma_mm)) << hs[0].centre_of_pressure_sigma_mm;
  EXPECT_TRUE(std::isnan(hs[0].centroid_sigma_mm)) << hs[0].centroid_sigma_mm;
  // One texel with a known σ inside it gives the centre of pressure a σ again.
  const auto k = place.grid.index(place.grid.width / 2 + 3, place.grid.height / 2);  // 0.15 mm off the centre
  s.value[k] = 0.3f, f.value[k] = 13.0f;
  const auto one = find_hotspots(f, &s, nullptr, place.raster, place.options(4.3), nullptr, &place.part.mesh);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_GT(one[0].centre_of_pressure_sigma_mm, 0);
}

TEST(Hotspots, ModelResidualMovesTheMeanAndAreaAsRaisingTheFieldByItDoes) {
  // σ all the model's allowance (HotspotOptions::model_sigma: no noise, nothing shared) and a residual r0 everywhere
  // (the truth is the field + r0): the mean's σ is then its residual term alone, r0 less the mean's rise as the
  // outline moves in, and the area's its band sum. Brute force: the place of the field raised by r0.
  const NoisyPlace place;
  const double threshold = 6.5, r0 = 0.2;
  HotspotOptions o = place.options(threshold);
  const ChartField model{place.grid, std::vector<float>(place.grid.size(), 0.5f)};
  const ChartField residual{place.grid, std::vector<float>(place.grid.size(), static_cast<float>(r0))};
  o.model_sigma = &model, o.residual = &residual;
  ChartField raised = place.clean;
  for (float& v : raised.value) v += static_cast<float>(r0);
  const auto hs = find_hotspots(place.clean, &model, nullptr, place.raster, o, nullptr, &place.part.mesh);
  const auto truth = find_hotspots(raised, nullptr, nullptr, place.raster, place.options(threshold), nullptr, &place.part.mesh);
  ASSERT_EQ(hs.size(), 1u);
  ASSERT_EQ(truth.size(), 1u);
  const double mean_shift = truth[0].mean - hs[0].mean, area_shift = truth[0].area_mm2 - hs[0].area_mm2;
  std::printf("raised by %.1f: mean %+.4f (sigma %.4f), area %+.4f mm2 (sigma %.4f)\n", r0, mean_shift, hs[0].mean_sigma, area_shift,
              hs[0].levels[0].area_sigma_mm2);
  EXPECT_NEAR(hs[0].mean_sigma, std::abs(mean_shift), 0.1 * std::abs(mean_shift));
  EXPECT_NEAR(hs[0].levels[0].area_sigma_mm2, std::abs(area_shift), 0.1 * std::abs(area_shift));
  EXPECT_LT(std::abs(mean_shift), 0.5 * r0);  // the outline's move offsets most of the texels' own
  // As noise (no model_sigma, no residual), the same σ averages down over the place's samples and moves its outline.
  const auto as_noise = find_hotspots(place.clean, &model, nullptr, place.raster, place.options(threshold), nullptr, &place.part.mesh);
  EXPECT_GT(as_noise[0].levels[0].area_sigma_mm2, 0);
  EXPECT_NE(as_noise[0].mean_sigma, hs[0].mean_sigma);
}

TEST(Hotspots, APlaceWithoutASeedIsNotReported) {
  // Two Gaussian places over the threshold; seeds (texels significant by their own σ) only in the first: the second
  // is dropped, its texels unlabelled, and the first keeps its extent, figures and id.
  const Flat f;
  const double r = 1.0;
  const ChartField p = f.field([&](double dx, double dy) {
    return 10 * std::exp(-((dx + 4) * (dx + 4) + dy * dy) / (2 * r * r)) + 6 * std::exp(-((dx - 4) * (dx - 4) + dy * dy) / (2 * r * r));
  });
  HotspotOptions o;
  o.thresholds = {3.0};
  std::vector<int> all_labels, seeded_labels;
  const auto all = find_hotspots(p, nullptr, nullptr, f.raster, o, &all_labels, &f.part.mesh);
  ASSERT_EQ(all.size(), 2u);
  std::vector<std::uint8_t> seeds(f.grid.size(), 0);
  for (int j = 0; j < f.grid.height; ++j)
    for (int i = 0; i < f.grid.width; ++i) seeds[f.grid.index(i, j)] = f.grid.uv(i, j).x() < f.centre.x();
  o.seeds = &seeds;
  const auto seeded = find_hotspots(p, nullptr, nullptr, f.raster, o, &seeded_labels, &f.part.mesh);
  ASSERT_EQ(seeded.size(), 1u);
  EXPECT_EQ(seeded[0].id, 1);
  EXPECT_DOUBLE_EQ(seeded[0].area_mm2, all[0].area_mm2);
  EXPECT_DOUBLE_EQ(seeded[0].peak, all[0].peak);
  EXPECT_TRUE(seeded[0].centroid_mm.isApprox(all[0].centroid_mm));
  for (std::size_t k = 0; k < seeded_labels.size(); ++k) EXPECT_EQ(seeded_labels[k], all_labels[k] == 1 ? 1 : 0) << k;
}

TEST(Hotspots, CentreOfPressureSigmaIsTheNoisesAlone) {
  // A texel's σ holds the noise and, as much again, an allowance for the field's model (HotspotOptions::model_sigma,
  // with a calibration the deblur's term): smooth over a place, it hardly moves its centre. The propagated σ is the
  // noise's (the scatter over noise realisations), not √2 times it (the lossless captures of scripts/bench-lossy.sh
  // read errors of 0.3 σ while it was).
  const NoisyPlace place;
  HotspotOptions o = place.options(3.0);
  ChartField total = place.sigma;
  for (float& v : total.value) v *= static_cast<float>(std::sqrt(2.0));
  o.model_sigma = &place.sigma;
  const auto truth = find_hotspots(place.clean, &total, nullptr, place.raster, o, nullptr, &place.part.mesh);
  ASSERT_EQ(truth.size(), 1u);
  cv::RNG rng(13);
  double sum_d2 = 0, sum_predicted = 0;
  const int runs = 200;
  for (int r = 0; r < runs; ++r) {
    const auto hs = find_hotspots(place.realise(rng), &total, nullptr, place.raster, o, nullptr, &place.part.mesh);
    ASSERT_GE(hs.size(), 1u);
    sum_d2 += (hs[0].centre_of_pressure_mm - truth[0].centre_of_pressure_mm).squaredNorm();
    sum_predicted += hs[0].centre_of_pressure_sigma_mm;
  }
  const double measured = std::sqrt(sum_d2 / runs), predicted = sum_predicted / runs;
  std::printf("centre of pressure with a model allowance: rms scatter %.4f mm, propagated sigma %.4f mm\n", measured, predicted);
  EXPECT_NEAR(predicted, measured, 0.15 * measured);
}

}  // namespace
}  // namespace clearfit
