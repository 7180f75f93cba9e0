#include <clearfit/atomic_file.hpp>
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>
#include <clearfit/reports/chart_images.hpp>
#include <clearfit/reports/colormap.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <stdexcept>
#include <string_view>

namespace clearfit {
namespace {

constexpr int kMargin = 20;
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kTextScale = 0.5;
constexpr int kMinBarHeight = 240;
const cv::Scalar kBlack(0, 0, 0), kWhite(255, 255, 255), kFrame(120, 120, 120);

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("ChartImageInput: " + what);
}

// 1, 2 or 5 times a power of ten: the one nearest to x (round_up) or the largest <= x.
double nice_number(double x, bool round_up) {
  const double p = std::pow(10.0, std::floor(std::log10(x)));
  const double f = x / p;
  if (round_up) return (f < 1.5 ? 1 : f < 3 ? 2 : f < 7 ? 5 : 10) * p;  // nearest on a log-ish scale
  return (f < 2 ? 1 : f < 5 ? 2 : 5) * p;                               // largest not above x
}

std::string format_tick(double v, double step) {
  const int decimals = std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)));
  return fixed_digits(std::abs(v) < 0.5 * step * 1e-6 ? 0.0 : v, decimals);
}

// Text in white with a black rim, readable on any colour.
void outlined_text(cv::Mat& img, const std::string& text, cv::Point at, double scale) {
  cv::putText(img, text, at, kFont, scale, kBlack, 3, cv::LINE_AA);
  cv::putText(img, text, at, kFont, scale, kWhite, 1, cv::LINE_AA);
}

cv::Size text_size(const std::string& text, double scale, int thickness = 1) {
  int baseline = 0;
  return cv::getTextSize(text, kFont, scale, thickness, &baseline);
}

}  // namespace

std::vector<double> nice_ticks(double lo, double hi, int target) {
  if (!(std::isfinite(lo) && std::isfinite(hi) && lo < hi) || target < 2) {
    throw std::invalid_argument("nice_ticks: need finite lo < hi and target >= 2");
  }
  double step = nice_number((hi - lo) / (target - 1), true);
  for (;;) {
    std::vector<double> ticks;
    for (double k = std::ceil(lo / step - 1e-9); k * step <= hi + 1e-9 * step; k += 1) {
      ticks.push_back(k == 0 ? 0.0 : k * step);  // no "-0"
    }
    if (ticks.size() >= 2) return ticks;
    step = nice_number(step * 0.99, false);
  }
}

void ChartImageInput::validate() const {
  require(field != nullptr, "field is null");
  const ChartGrid& g = field->grid;
  require(g.width > 0 && g.height > 0 && g.texel_mm > 0, "the field's grid is empty");
  require(field->value.size() == g.size(), "field has " + std::to_string(field->value.size()) +
                                               " values for " + std::to_string(g.size()) + " texels");
  require(hotspot_labels.empty() || hotspot_labels.size() == g.size(),
          "hotspot_labels has " + std::to_string(hotspot_labels.size()) + " entries for " +
              std::to_string(g.size()) + " texels");
  require(std::isfinite(range_lo) && std::isfinite(range_hi) && range_lo < range_hi,
          "range is not finite lo < hi");
  require(min_chart_width_px >= 1 && max_chart_width_px >= min_chart_width_px,
          "need 1 <= min_chart_width_px <= max_chart_width_px");
  Colormap::get(colormap);
}

ChartImageLayout write_chart_heatmap_png(const ChartImageInput& input, const std::filesystem::path& path) {
  input.validate();
  const ChartGrid& g = input.field->grid;
  const Colormap& cm = Colormap::get(input.colormap);

  // The chart at texel resolution, v up: grid row j is image row H-1-j.
  cv::Mat texels(g.height, g.width, CV_8UC3);
  cv::Mat labels(g.height, g.width, CV_32S, cv::Scalar(0));
  std::set<int> ids;
  for (int j = 0; j < g.height; ++j) {
    for (int i = 0; i < g.width; ++i) {
      Rgb8 c =
          cm.srgb8(normalise_to_range(input.field->value[g.index(i, j)], input.range_lo, input.range_hi));
      texels.at<cv::Vec3b>(g.height - 1 - j, i) = cv::Vec3b(c.b, c.g, c.r);
      if (!input.hotspot_labels.empty() && input.hotspot_labels[g.index(i, j)] > 0) {
        labels.at<int>(g.height - 1 - j, i) = input.hotspot_labels[g.index(i, j)];
        ids.insert(input.hotspot_labels[g.index(i, j)]);
      }
    }
  }

  ChartImageLayout L;
  double scale = 1;  // whole pixels per texel when upscaling, so every texel is the same block
  if (g.width < input.min_chart_width_px)
    scale = std::ceil(static_cast<double>(input.min_chart_width_px) / g.width);
  if (g.width * scale > input.max_chart_width_px)
    scale = static_cast<double>(input.max_chart_width_px) / g.width;
  L.chart_w = std::max(1, static_cast<int>(std::lround(g.width * scale)));
  L.chart_h = std::max(1, static_cast<int>(std::lround(g.height * scale)));
  L.px_per_mm = L.chart_w / (g.width * g.texel_mm);

  // Layout: title band, chart with the colour bar to its right, scale bar below.
  const int title_band = input.title.empty() ? kMargin : 60;
  L.chart_x = kMargin;
  L.chart_y = title_band;
  L.bar_w = 28;
  L.bar_x = L.chart_x + L.chart_w + 40;
  L.bar_y = L.chart_y;
  L.bar_h = std::max(L.chart_h, kMinBarHeight);
  L.ticks = nice_ticks(input.range_lo, input.range_hi);
  const double step = L.ticks.size() > 1 ? L.ticks[1] - L.ticks[0] : input.range_hi - input.range_lo;
  int label_w = text_size(input.unit, kTextScale).width;
  for (double t : L.ticks) label_w = std::max(label_w, text_size(format_tick(t, step), kTextScale).width);
  const int scale_band = 60;
  L.width = std::max(L.bar_x + L.bar_w + 10 + label_w + kMargin,
                     text_size(input.title, 0.8, 2).width + 2 * kMargin);
  L.height = L.chart_y + std::max(L.chart_h, L.bar_h) + scale_band;

  cv::Mat img(L.height, L.width, CV_8UC3, kWhite);
  const cv::Rect chart_rect(L.chart_x, L.chart_y, L.chart_w, L.chart_h);
  cv::Mat chart = img(chart_rect);
  cv::resize(texels, chart, chart_rect.size(), 0, 0, cv::INTER_NEAREST);
  cv::rectangle(img, chart_rect + cv::Point(-1, -1) + cv::Size(2, 2), kFrame, 1);

  // Hotspot outlines and their ids.
  if (!ids.empty()) {
    cv::Mat big;
    cv::resize(labels, big, chart_rect.size(), 0, 0, cv::INTER_NEAREST);
    for (int id : ids) {
      cv::Mat mask = big == id;
      std::vector<std::vector<cv::Point>> contours;
      cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
      const cv::Point offset(L.chart_x, L.chart_y);
      cv::drawContours(img, contours, -1, kBlack, 3, cv::LINE_8, cv::noArray(), INT_MAX, offset);
      cv::drawContours(img, contours, -1, kWhite, 1, cv::LINE_8, cv::noArray(), INT_MAX, offset);
      cv::Rect box = cv::boundingRect(mask);
      const std::string text = std::to_string(id);
      const cv::Size ts = text_size(text, 0.6, 2);
      cv::Point at(box.x + box.width + 4, box.y + ts.height);
      at.x = std::clamp(at.x, 0, std::max(0, L.chart_w - ts.width)) + L.chart_x;
      at.y = std::clamp(at.y, ts.height, std::max(ts.height, L.chart_h)) + L.chart_y;
      outlined_text(img, text, at, 0.6);
    }
  }

  // Colour bar: range_hi at the top row, range_lo at the bottom row.
  for (int y = 0; y < L.bar_h; ++y) {
    Rgb8 c = cm.srgb8(L.bar_h > 1 ? 1.0 - static_cast<double>(y) / (L.bar_h - 1) : 1.0);
    cv::line(img, {L.bar_x, L.bar_y + y}, {L.bar_x + L.bar_w - 1, L.bar_y + y}, cv::Scalar(c.b, c.g, c.r), 1);
  }
  cv::rectangle(img, cv::Rect(L.bar_x - 1, L.bar_y - 1, L.bar_w + 2, L.bar_h + 2), kFrame, 1);
  for (double t : L.ticks) {
    const int y = L.bar_y + static_cast<int>(std::lround(
                                (1 - normalise_to_range(t, input.range_lo, input.range_hi)) * (L.bar_h - 1)));
    cv::line(img, {L.bar_x + L.bar_w, y}, {L.bar_x + L.bar_w + 5, y}, kBlack, 1);
    const std::string text = format_tick(t, step);
    cv::putText(img, text, {L.bar_x + L.bar_w + 8, y + text_size(text, kTextScale).height / 2}, kFont,
                kTextScale, kBlack, 1, cv::LINE_AA);
  }
  if (!input.unit.empty()) {
    cv::putText(img, input.unit, {L.bar_x, L.bar_y - 8}, kFont, kTextScale, kBlack, 1, cv::LINE_AA);
  }

  // Scale bar: a 1-2-5 length near a fifth of the chart's width.
  L.scale_bar_mm = nice_number(std::max(g.width * g.texel_mm / 5, 1e-6), false);
  const int bar_px = std::max(1, static_cast<int>(std::lround(L.scale_bar_mm * L.px_per_mm)));
  const int sy = L.chart_y + std::max(L.chart_h, L.bar_h) + 30;
  L.scale_bar_x = L.chart_x;
  L.scale_bar_y = sy;
  L.scale_bar_px = bar_px;
  cv::line(img, {L.chart_x, sy}, {L.chart_x + bar_px, sy}, kBlack, 2);
  cv::line(img, {L.chart_x, sy - 6}, {L.chart_x, sy + 6}, kBlack, 2);
  cv::line(img, {L.chart_x + bar_px, sy - 6}, {L.chart_x + bar_px, sy + 6}, kBlack, 2);
  cv::putText(img, format_tick(L.scale_bar_mm, L.scale_bar_mm) + " mm", {L.chart_x + bar_px + 10, sy + 5},
              kFont, kTextScale, kBlack, 1, cv::LINE_AA);

  if (!input.title.empty()) {
    cv::putText(img, input.title, {kMargin, 38}, kFont, 0.8, kBlack, 2, cv::LINE_AA);
  }

  std::vector<unsigned char> png;
  if (!cv::imencode(".png", img, png))
    throw std::runtime_error("write_chart_heatmap_png: PNG encoding failed");
  write_file_atomically(path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  return L;
}

}  // namespace clearfit
