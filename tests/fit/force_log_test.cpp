// Calibration sessions, the force side: the force log reader, press
// segmentation, and the gauge-to-video clock alignment against simulated
// sessions with a known offset and drift (parameters not used to design the method).
#include <clearfit/error.hpp>
#include <clearfit/fit/force_log.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

namespace clearfit {
namespace {

namespace fs = std::filesystem;

struct Session {
  std::vector<double> press_start, press_force;  ///< gauge clock
  double hold_s = 5, rest_s = 8;
};

/// The true force (N, before tare) at gauge time t: ramps of 0.3 s, an overshoot of 8 % decaying in 0.4 s.
double true_force(const Session& s, double t) {
  for (std::size_t k = 0; k < s.press_start.size(); ++k) {
    const double a = s.press_start[k], b = a + s.hold_s, f = s.press_force[k];
    if (t < a || t > b + 0.3) continue;
    if (t < a + 0.3) return f * (t - a) / 0.3;
    if (t > b) return f * (1 - (t - b) / 0.3);
    return f * (1 + 0.08 * std::exp(-(t - a - 0.3) / 0.4));
  }
  return 0;
}

Session make_session(unsigned seed, int presses) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> force(0.1, 1.0), rest(6, 12);
  Session s;
  double t = 5;
  for (int k = 0; k < presses; ++k) {
    s.press_start.push_back(t);
    s.press_force.push_back(force(rng));
    t += s.hold_s + rest(rng);
  }
  return s;
}

/// Writes the gauge's log: rate hz, tare, noise, in unit `unit` (force_n or force_mn).
fs::path write_log(const Session& s, double hz, double tare, double noise, const std::string& unit, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, noise);
  const fs::path p = fs::temp_directory_path() / ("clearfit_force_" + std::to_string(::getpid()) + "_" + std::to_string(seed) + ".csv");
  std::ofstream out(p);
  out << "# gauge export\nsample,time_ms," << unit << "\n";
  const double scale = unit == "force_mn" ? 1000 : 1;
  const double end = s.press_start.back() + s.hold_s + 10;
  int i = 0;
  for (double t = 0; t < end; t += 1 / hz, ++i) out << i << "," << t * 1000 << "," << (true_force(s, t) + tare + n(rng)) * scale << "\n";
  return p;
}

/// The video's indenter signal: blanching of the force at gauge time (1+drift)·tv + offset, τ_on/τ_off lag, noise.
void video_signal(const Session& s, double offset, double drift, double fps, double tau_on, double tau_off, unsigned seed,
                  std::vector<double>& tv, std::vector<double>& y) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, 4e-4);
  double state = 0, video_end = (s.press_start.back() + s.hold_s + 8 - offset) / (1 + drift);
  for (double t = 0; t < video_end; t += 1 / fps) {
    const double f = true_force(s, (1 + drift) * (t - 0.5 / fps) + offset);  // over the frame interval before t, at its middle
    const double target = 0.03 / (1 + std::exp(-(f / 0.0314 - 12) / 3));  // logistic in mean pressure of a 2 mm indenter
    state += (target - state) * (1 - std::exp(-1 / fps / (target > state ? tau_on : tau_off)));
    tv.push_back(t);
    y.push_back(state + n(rng));
  }
}

TEST(ForceLog, ReadsUnitsTareAndFindsEveryPress) {
  const Session s = make_session(41, 12);
  const fs::path p = write_log(s, 100, 0.037, 0.004, "force_mn", 1);
  const ForceLog log = read_force_log(p);
  fs::remove(p);
  EXPECT_NEAR(log.tare_n, 0.037, 0.003);
  const auto presses = find_presses(log);
  ASSERT_EQ(presses.size(), s.press_start.size());
  for (std::size_t k = 0; k < presses.size(); ++k) {
    EXPECT_NEAR(presses[k].force_n, s.press_force[k], 0.01 + 0.02 * s.press_force[k]) << k;  // overshoot settled out
    EXPECT_GE(presses[k].hold_start_s, s.press_start[k] + 1.0);
    EXPECT_LE(presses[k].hold_end_s, s.press_start[k] + s.hold_s + 0.3);
    EXPECT_LT(presses[k].rest_end_s, s.press_start[k]);
    if (k > 0) EXPECT_GT(presses[k].rest_start_s, s.press_start[k - 1] + s.hold_s);
  }
}

TEST(ForceLog, AlignsTheGaugeClockToTheVideo) {
  for (const auto& [seed, offset, drift] : {std::tuple{7u, 3.7, 300e-6}, std::tuple{8u, -12.25, -450e-6}, std::tuple{9u, 0.4, 120e-6}}) {
    const Session s = make_session(seed, 14);
    const fs::path p = write_log(s, 50 + seed, 0.02, 0.003, "force_n", seed);
    const ForceLog log = read_force_log(p);
    fs::remove(p);
    std::vector<double> tv, y;
    video_signal(s, offset, drift, 30, 0.22, 1.9, seed, tv, y);  // the person's time constants differ from the model's
    const ClockAlignment a = align_clocks(log, find_presses(log), tv, y);
    std::printf("seed %u: offset %.4f ± %.4f s (truth %.4f), drift %.1f ± %.1f ppm (truth %.1f), %d events, 2nd peak %.2f\n", seed,
                a.offset_s, a.offset_sigma_s, offset, a.drift * 1e6, a.drift_sigma * 1e6, drift * 1e6, a.events, a.second_peak_ratio);
    // What the press windows need: gauge times mapped to the video within 0.15 s over the whole session
    // (the person's time constants differ from the model's; edges of a nonlinear response time to ~0.1 s).
    for (double t = 0; t <= tv.back(); t += 10) EXPECT_NEAR(a.to_gauge(t), (1 + drift) * t + offset, 0.15) << "at " << t << " s";
    // The drift itself is resolved only to its σ in a 4-minute session: the estimate must own up to it.
    EXPECT_LT(std::abs(a.drift - drift), 3 * a.drift_sigma + 20e-6);
    EXPECT_LT(std::abs(a.offset_s - offset), 3 * a.offset_sigma_s + 0.02);
    // The whole-trace fit (the skin's sigmoid and both time constants fitted) times the clock to 10 ms at 30 fps
    // (the events' fit alone: 20-30 ms).
    EXPECT_LT(std::abs(a.offset_s - offset), 0.01);
    EXPECT_TRUE(a.trace_fit);
    EXPECT_GE(a.events, 20);
  }
}

TEST(ForceLog, RefusesAmbiguousAlignmentAndBadLogs) {
  Session s;  // equal forces, equal rests: every shift by a period fits as well
  for (int k = 0; k < 10; ++k) s.press_start.push_back(5 + 13.0 * k), s.press_force.push_back(0.6);
  const fs::path p = write_log(s, 100, 0, 0.002, "force_n", 3);
  const ForceLog log = read_force_log(p);
  fs::remove(p);
  std::vector<double> tv, y;
  video_signal(s, 2.0, 0, 30, 0.3, 1.5, 3, tv, y);
  EXPECT_THROW(align_clocks(log, find_presses(log), tv, y), InputError);

  const fs::path bad = fs::temp_directory_path() / ("clearfit_force_bad_" + std::to_string(::getpid()) + ".csv");
  auto expect_refused = [&](const std::string& text, const std::string& needle) {
    std::ofstream(bad) << text;
    try {
      read_force_log(bad);
      ADD_FAILURE() << "accepted: " << text;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  std::string rows;
  for (int i = 0; i < 20; ++i) rows += std::to_string(i * 0.1) + "," + std::to_string(0.1 * (i % 3)) + "\n";
  expect_refused("time,force\n" + rows, "no time column with a unit");
  expect_refused("time_s,force\n" + rows, "no force column with a unit");
  expect_refused("time_s,force_n\n0,0\n0.1,0.2\n0.1,0.3\n" + rows, "line 4");
  expect_refused("time_s,force_n\n0,0\n0.1,nan\n" + rows, "not a finite number");
  expect_refused("time_s,force_n\n0,0\n0.1,0.2\n", "at least 10");
  std::string clipped = "time_s,force_n\n";
  for (int i = 0; i < 100; ++i) clipped += std::to_string(i * 0.1) + "," + (i % 4 == 0 ? "5.0" : "0.1") + "\n";
  expect_refused(clipped, "clipped");
  std::string flat = "time_s,force_n\n";
  for (int i = 0; i < 100; ++i) flat += std::to_string(i * 0.1) + ",0.001\n";
  std::ofstream(bad) << flat;
  EXPECT_THROW(find_presses(read_force_log(bad)), InputError);
  fs::remove(bad);
}

}  // namespace
}  // namespace clearfit
