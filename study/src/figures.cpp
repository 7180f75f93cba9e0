#include "figures.hpp"

#include "files.hpp"

#include <clearfit/format.hpp>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace clearfit::study {
namespace {

/// A round step giving about `n` intervals over `span`.
double nice_step(double span, int n) {
  const double raw = span / n, mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 2.5, 5.0, 10.0})
    if (m * mag >= raw) return m * mag;
  return 10 * mag;
}

std::string tick(double v) { return significant_digits(std::abs(v) < 1e-12 ? 0.0 : v, 4); }

}  // namespace

void write_line_plot(const std::vector<Curve>& curves, const std::string& title, const std::string& x_label,
                     const std::string& y_label, double reference_y, const std::filesystem::path& path) {
  const int W = 1000, H = 620, left = 90, right = 200, top = 64, bottom = 65, font = cv::FONT_HERSHEY_SIMPLEX;
  double x0 = INFINITY, x1 = -INFINITY, y0 = std::isfinite(reference_y) ? reference_y : INFINITY, y1 = -y0;
  if (!std::isfinite(reference_y)) y1 = -INFINITY;
  for (const Curve& c : curves)
    for (std::size_t k = 0; k < c.x.size(); ++k)
      if (std::isfinite(c.y[k])) x0 = std::min(x0, c.x[k]), x1 = std::max(x1, c.x[k]), y0 = std::min(y0, c.y[k]), y1 = std::max(y1, c.y[k]);
  if (!(x0 < x1)) x0 = 0, x1 = 1;
  if (!(y0 < y1)) y0 = std::isfinite(y0) ? y0 - 1 : 0, y1 = y0 + 2;
  const double xs = nice_step(x1 - x0, 8), ys = nice_step(y1 - y0, 6);
  x0 = std::floor(x0 / xs) * xs, x1 = std::ceil(x1 / xs) * xs, y0 = std::floor(y0 / ys) * ys, y1 = std::ceil(y1 / ys) * ys;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  auto px = [&](double x, double y) {
    return cv::Point(int(std::lround(left + (x - x0) / (x1 - x0) * (W - left - right))),
                     int(std::lround(H - bottom - (y - y0) / (y1 - y0) * (H - top - bottom))));
  };
  const cv::Scalar black(0, 0, 0), grey(210, 210, 210);
  for (double t = x0; t <= x1 + 1e-9 * xs; t += xs) {
    cv::line(img, px(t, y0), px(t, y1), grey, 1);
    cv::putText(img, tick(t), px(t, y0) + cv::Point(-10, 22), font, 0.45, black, 1, cv::LINE_AA);
  }
  for (double t = y0; t <= y1 + 1e-9 * ys; t += ys) {
    cv::line(img, px(x0, t), px(x1, t), grey, 1);
    const std::string s = tick(t);
    cv::putText(img, s, px(x0, t) + cv::Point(-12 - 9 * int(s.size()), 5), font, 0.45, black, 1, cv::LINE_AA);
  }
  if (std::isfinite(reference_y))
    for (double x = x0; x < x1; x += (x1 - x0) / 80) cv::line(img, px(x, reference_y), px(std::min(x1, x + (x1 - x0) / 160), reference_y), black, 1);
  cv::rectangle(img, px(x0, y1), px(x1, y0), black, 1);
  cv::putText(img, title, cv::Point(left, top - 24), font, 0.6, black, 1, cv::LINE_AA);
  cv::putText(img, x_label, cv::Point((W - right) / 2, H - 18), font, 0.55, black, 1, cv::LINE_AA);
  cv::putText(img, y_label, cv::Point(8, top - 8), font, 0.45, black, 1, cv::LINE_AA);
  for (std::size_t c = 0; c < curves.size(); ++c) {
    // Colours evenly around the hue circle (OpenCV's HSV: hue 0..179).
    cv::Mat hsv(1, 1, CV_8UC3, cv::Scalar(double(180 * c / std::max<std::size_t>(1, curves.size())), 220, 200)), bgr;
    cv::cvtColor(hsv, bgr, cv::COLOR_HSV2BGR);
    const cv::Vec3b v = bgr.at<cv::Vec3b>(0, 0);
    const cv::Scalar colour(v[0], v[1], v[2]);
    std::vector<cv::Point> run;
    auto flush = [&] {
      if (run.size() > 1) cv::polylines(img, run, false, colour, 2, cv::LINE_AA);
      run.clear();
    };
    for (std::size_t k = 0; k < curves[c].x.size(); ++k) {
      if (std::isfinite(curves[c].y[k])) run.push_back(px(curves[c].x[k], curves[c].y[k]));
      else flush();
    }
    flush();
    const cv::Point lg(W - right + 20, top + 10 + 24 * int(c));
    cv::line(img, lg, lg + cv::Point(24, 0), colour, 3, cv::LINE_AA);
    cv::putText(img, curves[c].label, lg + cv::Point(32, 5), font, 0.5, black, 1, cv::LINE_AA);
  }
  std::vector<unsigned char> png;
  cv::imencode(".png", img, png);
  write_text_atomically(path, std::string(png.begin(), png.end()));
}

}  // namespace clearfit::study
