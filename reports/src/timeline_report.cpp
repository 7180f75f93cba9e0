#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>
#include <clearfit/npy.hpp>
#include <clearfit/reports/timeline_report.hpp>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace clearfit {
namespace {

using json = nlohmann::json;

json finite(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

json fit_json(const TimeConstantFit& f) {
  json j = {{"fitted", f.fitted}, {"bins", f.bins}, {"note", f.note}};
  if (!f.fitted) return j;
  j["tau_s"] = finite(f.tau_s);
  j["tau_sigma_s"] = finite(f.tau_sigma_s);
  j["t0_s"] = finite(f.t0_s);
  j["t0_sigma_s"] = finite(f.t0_sigma_s);
  j["amplitude"] = finite(f.amplitude);
  j["offset"] = finite(f.offset);
  j["rms"] = finite(f.rms);
  return j;
}

/// Tick step of about `n` intervals over `span`: 1, 2 or 5 times a power of ten.
double tick_step(double span, int n) {
  const double raw = std::max(span, 1e-12) / n, p = std::pow(10.0, std::floor(std::log10(raw)));
  const double m = raw / p;
  return (m <= 1 ? 1 : m <= 2 ? 2 : m <= 5 ? 5 : 10) * p;
}

}  // namespace

json timeline_json(const Assessment& a) {
  const TimeAnalysis& t = a.time;
  if (!t.present) return nullptr;
  const std::string unit = a.calibrated ? "kPa" : "signal";
  json places = json::array();
  for (const HotspotTimeline& h : t.hotspots) {
    json levels = json::array();
    for (const ThresholdTime& l : h.thresholds)
      levels.push_back({{"threshold", l.threshold}, {"unit", unit}, {"threshold_signal", finite(l.signal)}, {"texels", l.texels},
                        {"reached", l.reached}, {"first_above_s", l.reached ? finite(l.first_above_s) : json(nullptr)},
                        {"time_above_s", finite(l.time_above_s)}});
    places.push_back({{"id", h.hotspot}, {"onset", fit_json(h.onset)}, {"refill", fit_json(h.refill)}, {"thresholds", levels},
                      {"figure", "timeline_place_" + std::to_string(h.hotspot) + ".png"}});
  }
  const ChartGrid& g = t.texel_grid;
  return {{"fps", t.fps},
          {"frames", t.frames},
          {"bins", t.bins},
          {"bin_frames", t.bin_frames},
          {"bin_s", t.bin_frames / t.fps},
          {"press_frame", t.press_frame},
          {"release_frame", t.release_frame >= 0 ? json(t.release_frame) : json(nullptr)},
          {"release_s", t.release_frame >= 0 ? json(t.release_frame / t.fps) : json(nullptr)},
          {"cell_px", t.cell_px},
          {"memory_mb", t.memory_bytes / 1048576.0},
          {"texel_grid", {{"texel_mm", g.texel_mm}, {"uv_origin_mm", {g.uv_origin.x(), g.uv_origin.y()}}, {"width", g.width}, {"height", g.height}}},
          {"places", places},
          {"model", "signal per bin: ln(G/G0) of the place's cells minus the bin's median over the seen cells; onset: "
                    "A·(1 − exp(−(t − t0)/tau)) after t0; refill: c + A·exp(−(t − t_release)/tau); times in s from the first frame "
                    "of the capture holding the worn phase"}};
}

cv::Mat timeline_figure(const TimeAnalysis& t, const HotspotTimeline& h, bool calibrated) {
  const int W = 960, H = 440, left = 80, right = 20, top = 56, bottom = 50, font = cv::FONT_HERSHEY_SIMPLEX;
  double x0 = 0, x1 = t.time_s.empty() ? 1 : t.time_s.back() + 0.5 * t.bin_frames / t.fps, y0 = 0, y1 = 0;
  for (double v : h.signal)
    if (std::isfinite(v)) y0 = std::min(y0, v), y1 = std::max(y1, v);
  for (const ThresholdTime& l : h.thresholds)
    if (std::isfinite(l.signal)) y1 = std::max(y1, l.signal);
  if (!(y1 > y0)) y1 = y0 + 1e-3;
  const double pad = 0.05 * (y1 - y0);
  y0 -= pad, y1 += pad;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  auto px = [&](double x, double y) {
    return cv::Point(static_cast<int>(std::lround(left + (x - x0) / (x1 - x0) * (W - left - right))),
                     static_cast<int>(std::lround(H - bottom - (y - y0) / (y1 - y0) * (H - top - bottom))));
  };
  const cv::Scalar black(0, 0, 0), grey(215, 215, 215), blue(180, 90, 20), green(40, 150, 40), red(40, 40, 200), orange(0, 140, 255);
  const double xs = tick_step(x1 - x0, 10), ys = tick_step(y1 - y0, 6);
  for (double x = 0; x <= x1; x += xs) {
    cv::line(img, px(x, y0), px(x, y1), grey, 1);
    cv::putText(img, significant_digits(x, 3), px(x, y0) + cv::Point(-8, 20), font, 0.42, black, 1,
                cv::LINE_AA);
  }
  for (double y = std::ceil(y0 / ys) * ys; y <= y1; y += ys) {
    cv::line(img, px(x0, y), px(x1, y), grey, 1);
    const std::string s = significant_digits(std::abs(y) < 1e-12 ? 0.0 : y, 3);
    cv::putText(img, s, px(x0, y) + cv::Point(-10 - 8 * static_cast<int>(s.size()), 5), font, 0.42, black, 1, cv::LINE_AA);
  }
  cv::rectangle(img, px(x0, y1), px(x1, y0), black, 1);
  // Thresholds (dashed), labelled in their own unit.
  for (const ThresholdTime& l : h.thresholds) {
    if (!std::isfinite(l.signal) || l.signal < y0 || l.signal > y1) continue;
    for (double x = x0; x < x1; x += (x1 - x0) / 60) cv::line(img, px(x, l.signal), px(std::min(x1, x + (x1 - x0) / 120), l.signal), red, 1);
    cv::putText(img, significant_digits(l.threshold, 3) + (calibrated ? " kPa" : ""),
                px(x1, l.signal) + cv::Point(-70, -4), font, 0.42, red, 1, cv::LINE_AA);
  }
  std::vector<cv::Point> run;
  auto flush = [&] {
    if (run.size() > 1) cv::polylines(img, run, false, blue, 2, cv::LINE_AA);
    run.clear();
  };
  for (std::size_t k = 0; k < h.signal.size() && k < t.time_s.size(); ++k) {
    if (std::isfinite(h.signal[k])) run.push_back(px(t.time_s[k], h.signal[k]));
    else flush();
  }
  flush();
  std::string title = "Place " + std::to_string(h.hotspot) + " over time";
  if (h.onset.fitted) {
    cv::line(img, px(h.onset.t0_s, y0), px(h.onset.t0_s, y1), green, 1, cv::LINE_AA);
    cv::putText(img, "onset", px(h.onset.t0_s, y1) + cv::Point(4, 14), font, 0.42, green, 1, cv::LINE_AA);
    title += ": onset " + significant_digits(h.onset.t0_s, 3) + " s (tau " +
             significant_digits(h.onset.tau_s, 2) + " s)";
  }
  if (t.release_frame >= 0) {
    const double tr = t.release_frame / t.fps;
    cv::line(img, px(tr, y0), px(tr, y1), orange, 1, cv::LINE_AA);
    cv::putText(img, "removed", px(tr, y1) + cv::Point(4, 14), font, 0.42, orange, 1, cv::LINE_AA);
    if (h.refill.fitted) {
      std::vector<cv::Point> curve;
      for (double x = tr; x <= x1; x += (x1 - tr) / 100 + 1e-9)
        curve.push_back(px(x, h.refill.offset + h.refill.amplitude * std::exp(-(x - h.refill.t0_s) / h.refill.tau_s)));
      cv::polylines(img, curve, false, orange, 1, cv::LINE_AA);
      title += ", refill tau " + significant_digits(h.refill.tau_s, 2) + " +/- " +
               significant_digits(h.refill.tau_sigma_s, 1) + " s";
    }
  }
  cv::putText(img, title, cv::Point(left, top - 24), font, 0.55, black, 1, cv::LINE_AA);
  cv::putText(img, "time (s)", cv::Point((W - right) / 2, H - 12), font, 0.5, black, 1, cv::LINE_AA);
  cv::putText(img, "signal ln(G/G0)", cv::Point(8, top - 6), font, 0.42, black, 1, cv::LINE_AA);
  return img;
}

std::vector<std::string> write_timeline_outputs(const Assessment& a, const std::filesystem::path& folder) {
  const TimeAnalysis& t = a.time;
  std::vector<std::string> written;
  if (!t.present) return written;
  // timeline.csv: one row per place and bin.
  std::ostringstream csv;
  csv.precision(7);
  csv << "place,t_s,frames,signal" << (a.calibrated ? ",pressure_kpa" : "");
  const std::string unit = a.calibrated ? "kpa" : "signal";
  if (!t.hotspots.empty())
    for (const ThresholdTime& l : t.hotspots.front().thresholds)
      csv << ",level_" << significant_digits(l.threshold, 3) << "_" << unit << "_signal";
  csv << "\n";
  auto cell = [&](double v) {
    if (std::isfinite(v)) csv << v;
  };
  for (const HotspotTimeline& h : t.hotspots)
    for (std::size_t b = 0; b < h.signal.size(); ++b) {
      const int first = static_cast<int>(b) * t.bin_frames;
      csv << h.hotspot << "," << t.time_s[b] << "," << std::min(t.bin_frames, t.frames - first) << ",";
      cell(h.signal[b]);
      if (a.calibrated) csv << ",", cell(h.kpa[b]);
      for (const auto& level : h.level_signal) csv << ",", cell(level.empty() ? NAN : level[b]);
      csv << "\n";
    }
  write_file_atomically(folder / "timeline.csv", csv.str());
  written.push_back("timeline.csv");
  npy::write_float32(folder / "timeline_time_s.npy", {t.time_s.size()}, [&](std::size_t k, float* out) { out[0] = static_cast<float>(t.time_s[k]); });
  written.push_back("timeline_time_s.npy");
  const ChartGrid& g = t.texel_grid;
  auto texels = [&](const std::vector<float>& v, const std::string& name) {
    npy::write_float32(folder / name, {static_cast<std::size_t>(t.bins), static_cast<std::size_t>(g.height), static_cast<std::size_t>(g.width)},
                       [&](std::size_t b, float* out) { std::copy_n(v.begin() + static_cast<std::ptrdiff_t>(b * g.size()), g.size(), out); });
    written.push_back(name);
  };
  if (t.bins > 0 && g.size() > 0) {
    texels(t.texel_signal, "timeline_texels_signal.npy");
    if (a.calibrated && t.texel_kpa.size() == t.texel_signal.size()) texels(t.texel_kpa, "timeline_texels_pressure_kpa.npy");
  }
  for (const HotspotTimeline& h : t.hotspots) {
    std::vector<std::uint8_t> png;
    const std::string name = "timeline_place_" + std::to_string(h.hotspot) + ".png";
    if (!cv::imencode(".png", timeline_figure(t, h, a.calibrated), png)) throw InputError((folder / name).string(), "", "cannot encode the figure");
    write_file_atomically(folder / name, std::string(png.begin(), png.end()));
    written.push_back(name);
  }
  return written;
}

}  // namespace clearfit
