#pragma once
// A study manifest (YAML, schema clearfit.study/1): participants with their
// pressure calibration, conditions (a scene: part, camera, map; optionally the
// bump of the study's plate), and trials (the captures of one participant in
// one condition). Paths are relative to the manifest. Every trial is one
// independent job (see jobs.hpp).
//
//   study: bump-cohort
//   participants:
//     - {id: p1, calibration: cal/p1.json}            # person: defaults to id
//   conditions:
//     - {id: d4-h1, scene: plate.yaml, bump: {diameter_mm: 4, height_mm: 1}}   # centre_mm: [x, y] (else found)
//   trials:
//     - {id: p1-d4-h1-1, participant: p1, condition: d4-h1, both: p1/d4-h1-1.mkv, force_n: 0.8}
//     - {id: p1-d4-h1-2, participant: p1, condition: d4-h1, baseline: a.mkv, worn: b.mkv}
//   analysis: {pressure: true, window_frames: 100, profile: {length_mm: 14, angle_step_deg: 20, sample_mm: 0.05}}
#include <clearfit/study/analysis.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace clearfit::study {

struct Participant {
  std::string id, person;                          ///< person: the name in the calibration file
  std::optional<std::filesystem::path> calibration;
};

struct Bump {
  double diameter_mm = 0, height_mm = 0;
  std::optional<Vec2> centre_mm;  ///< (x, y) of its axis in the part frame; the largest place's centroid when not given
};

struct Condition {
  std::string id;
  std::filesystem::path scene;
  std::optional<Bump> bump;
};

struct Trial {
  std::string id, participant, condition;
  std::filesystem::path baseline, worn, both;  ///< two captures, or one holding both phases
  std::optional<double> force_n;               ///< the force plate's reading, N
  int line = 0;                                ///< line in the manifest
  /// Why this trial cannot run (duplicate id, unknown participant or condition,
  /// kPa asked without a calibration), starting with its line in the manifest:
  /// its job fails with this message, the others run. Empty when runnable.
  std::string problem;
};

struct AnalysisOptions {
  bool pressure = false;   ///< kPa asked: every trial's participant needs a calibration
  int window_frames = 0;   ///< 0: the scene's
  ProfileOptions profile;
  void validate() const;
};

struct Manifest {
  std::filesystem::path path;
  std::string study;
  std::vector<Participant> participants;
  std::vector<Condition> conditions;
  std::vector<Trial> trials;
  AnalysisOptions analysis;
  bool has_participant(const std::string& id) const;
  bool has_condition(const std::string& id) const;
  /// Throw std::out_of_range for an unknown id.
  const Participant& participant(const std::string& id) const;
  const Condition& condition(const std::string& id) const;
};

/// Reads and checks a manifest. The manifest as a whole is refused (InputError
/// naming the file, the line and the key) for invalid YAML, unknown keys,
/// wrong types, duplicate participant or condition ids, a trial with neither
/// two captures nor one, a force that is not positive. What concerns one trial
/// only (a duplicate trial id, an unknown participant or condition, kPa asked
/// without a calibration) is set in Trial::problem: that job fails with the
/// message and the study goes on. Missing input files are found when the job runs.
Manifest read_manifest(const std::filesystem::path& path);

}  // namespace clearfit::study
