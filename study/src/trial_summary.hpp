#pragma once
#include <clearfit/study/manifest.hpp>

#include <nlohmann/json.hpp>

#include <filesystem>

namespace clearfit::study {

/// The figures of one assessed trial, from its assessment folder (report.json,
/// signal.npy, pressure.npy, chart_points.npy): peak and mean pressure,
/// hotspots, the mean colour change inside the bump's contact disc (centred on
/// the bump's axis when given, else on the largest place), the mean pressure
/// from the force plate, the radial profile of the signal and its
/// rim-to-centre ratio — profiles and discs in the part's x–y plane, in mm. Throws std::runtime_error when an
/// output is missing or inconsistent.
nlohmann::json summarise_trial(const Manifest& manifest, const Trial& trial, const std::filesystem::path& assessment);

/// The chart field stored in an assessment's .npy, on the grid report.json gives.
ChartField read_assessment_field(const std::filesystem::path& assessment, const std::string& npy);

}  // namespace clearfit::study
