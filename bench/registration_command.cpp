// clearfit-bench registration: the motion registration's time per frame
// (registration.hpp) at a size, on synthetic skin-coloured frames with a
// ridge-and-mottle texture and sensor noise, moved by a known drift, and its
// error against that motion.
#include <clearfit/cli/commands.hpp>
#include <clearfit/fit/registration.hpp>

#include <opencv2/core.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <memory>
#include <numbers>
#include <random>

namespace clearfit::cli {

namespace {

/// Process CPU time (all threads), ms.
double cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec * 1e3 + t.tv_nsec * 1e-6;
}

/// A frame whose content at q is seen at q + shift: ridges (5 px period) and mottle on skin
/// colours, noise of `noise` codes.
cv::Mat frame(cv::Size size, const Vec2& shift, std::uint32_t seed, double noise) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  struct Wave { double kx, ky, phase, amp; };
  std::vector<Wave> waves;
  for (int i = 0; i < 3; ++i) {  // ridges: 5 px, a little wavy
    const double dir = 0.6 + 0.2 * i, k = 2 * std::numbers::pi / (5.0 + 0.4 * i);
    waves.push_back({k * std::cos(dir), k * std::sin(dir), 2 * std::numbers::pi * u(rng), 0.03});
  }
  for (int i = 0; i < 12; ++i) {  // mottle: 15–60 px
    const double dir = 2 * std::numbers::pi * u(rng), k = 2 * std::numbers::pi / (15 + 45 * u(rng));
    waves.push_back({k * std::cos(dir), k * std::sin(dir), 2 * std::numbers::pi * u(rng), 0.02});
  }
  std::mt19937 noise_rng(seed);
  std::normal_distribution<float> n(0.f, static_cast<float>(noise));
  cv::Mat out(size, CV_8UC3);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) {
      double m = 0;
      const double qx = x - shift.x(), qy = y - shift.y();
      for (const Wave& w : waves) m += w.amp * std::cos(w.kx * qx + w.ky * qy + w.phase);
      out.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(110 * (1 + m) + n(noise_rng)),
                                          cv::saturate_cast<uchar>(130 * (1 + m) + n(noise_rng)),
                                          cv::saturate_cast<uchar>(190 * (1 + m) + n(noise_rng)));
    }
  return out;
}

Run add_bench_registration(CLI::App& app) {
  struct Opts {
    int width = 1920, height = 1080, frames = 20;
    double noise = 2.0, drift = 0.1;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = app.add_subcommand("registration", "Motion registration: time per frame and error against a known drift");
  sub->add_option("--width", o->width, "Frame width, px")->capture_default_str()->check(CLI::Range(256, 8192));
  sub->add_option("--height", o->height, "Frame height, px")->capture_default_str()->check(CLI::Range(256, 8192));
  sub->add_option("--frames", o->frames, "Frames measured after the reference's")->capture_default_str()->check(CLI::Range(1, 1000));
  sub->add_option("--noise", o->noise, "Sensor noise, 8-bit codes RMS")->capture_default_str()->check(CLI::Range(0.0, 50.0));
  sub->add_option("--drift", o->drift, "Drift per frame, px")->capture_default_str()->check(CLI::Range(0.0, 2.0));
  return [o] {
    const cv::Size size(o->width, o->height);
    const cv::Rect roi(size.width / 6, size.height / 6, size.width * 2 / 3, size.height * 2 / 3);
    MotionRegistration reg(size, roi, {});
    const int first = reg.options().reference_frames, total = first + o->frames;
    std::fprintf(stderr, "bench: rendering %d frames of %dx%d\n", total, size.width, size.height);
    std::vector<cv::Mat> frames;
    std::vector<Vec2> truth;
    for (int k = 0; k < total; ++k) {
      truth.push_back(Vec2(0.8, 0.6) * o->drift * k);
      frames.push_back(frame(size, truth.back(), 100 + k, o->noise));
    }
    Similarity previous;
    double wall = 0, cpu = 0, worst = 0;
    for (int k = 0; k < total; ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      const double c0 = cpu_ms();
      const bool building = reg.reference_open();
      const RegistrationResult r = building ? reg.add_to_reference(frames[k], previous) : reg.measure(frames[k], previous);
      if (building && !reg.reference_open()) reg.close_reference();
      if (!building) {
        wall += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        cpu += cpu_ms() - c0;
        if (!r.found) worst = 1e9;
        for (const Vec2& q : {Vec2(roi.x, roi.y), Vec2(roi.br().x, roi.br().y), Vec2(roi.x + 0.5 * roi.width, roi.y + 0.5 * roi.height)})
          worst = std::max(worst, (r.motion.displacement(q) - truth[k]).norm());
      }
      if (r.found) previous = r.motion;
    }
    std::printf("registration %dx%d, roi %dx%d, %zu patches, %d frames: %.1f ms per frame (wall), %.1f ms CPU (all threads); "
                "error at most %.4f px\n",
                size.width, size.height, roi.width, roi.height, reg.patches().size(), o->frames, wall / o->frames, cpu / o->frames, worst);
    return 0;
  };
}

}  // namespace

static const Registration registered{"registration", 40, add_bench_registration};

}  // namespace clearfit::cli
