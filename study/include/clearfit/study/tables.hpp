#pragma once
// The reduce step of a study: every job's record → tables per trial,
// participant and condition (CSV and one JSON), the radial profiles, and the
// study's regressions (per participant: mean colour change in the contact area
// against mean pressure, linear as in the study — R², slope, p — and the
// logistic calibration model; summary: mean R², how many participants are
// significant at 5 % and 10 %).
#include <clearfit/study/jobs.hpp>

#include <nlohmann/json.hpp>

#include <filesystem>
#include <vector>

namespace clearfit::study {

struct StudyTables {
  nlohmann::json summary;                   ///< what study.json holds
  std::vector<std::filesystem::path> files;  ///< written, in order
  std::size_t ok = 0, failed = 0;
};

/// Reads every job record under context.out and writes trials.csv,
/// participants.csv, conditions.csv, profiles.csv and study.json there
/// (atomically). Jobs without a record count as failed ("not run").
StudyTables reduce_study(const Manifest& manifest, const RunContext& context);

}  // namespace clearfit::study
