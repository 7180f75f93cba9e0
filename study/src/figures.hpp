#pragma once
// The study's figures: line plots (one curve per condition) as PNG.
#include <filesystem>
#include <string>
#include <vector>

namespace clearfit::study {

struct Curve {
  std::string label;
  std::vector<double> x, y;  ///< NaN y breaks the line
};

/// A line plot with axes, grid, ticks, a legend and an optional horizontal
/// reference line (NaN: none), written atomically as PNG.
void write_line_plot(const std::vector<Curve>& curves, const std::string& title, const std::string& x_label,
                     const std::string& y_label, double reference_y, const std::filesystem::path& path);

}  // namespace clearfit::study
