#pragma once
// The worn phase over time in an assessment's outputs (docs/assessment-outputs.md):
// timeline.csv (per place and time bin), timeline_time_s.npy, the per-texel
// series on the coarse chart grid (timeline_texels_signal.npy, and
// timeline_texels_pressure_kpa.npy with a calibration) and a figure per place
// (timeline_place_<id>.png: its series, the thresholds, the onset and the
// refill marked), and the "timeline" object of report.json.
#include <clearfit/fit/assessment.hpp>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace clearfit {

/// report.json's "timeline" (null when the assessment has no time series).
nlohmann::json timeline_json(const Assessment& a);

/// Writes the files above into `folder`; returns their names (none without a time series).
std::vector<std::string> write_timeline_outputs(const Assessment& a, const std::filesystem::path& folder);

/// The figure of one place (BGR8), for tests and the writer.
cv::Mat timeline_figure(const TimeAnalysis& t, const HotspotTimeline& h, bool calibrated);

}  // namespace clearfit
