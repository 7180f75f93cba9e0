#pragma once
// A study's trials as independent jobs. Job i assesses trial i with the
// clearfit executable (`clearfit assess`, one process per job: memory is
// bounded per job and a crash stays in its job), then computes the trial's
// summary (analysis.hpp) from the assessment's outputs. Each job writes
// OUT/jobs/<trial>/job.json last and atomically: a job whose record says
// "ok" with the same content hash is skipped when the study runs again, so a
// killed study resumes where it stopped. A failed job is recorded with its
// error and does not stop the others. The reduce step reads every record and
// writes the tables (study_tables.hpp). The same per-job entry point runs a
// local pool (`study run`) or a Slurm array task (`study job --index I`).
#include <clearfit/study/manifest.hpp>

#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace clearfit::study {

struct RunContext {
  std::filesystem::path clearfit_exe;  ///< the executable that runs `assess`
  std::filesystem::path out;           ///< the study's output folder
  std::string version;                 ///< clearfit's version (part of every job's hash)
};

struct JobRecord {
  std::string trial;
  std::size_t index = 0;
  std::string hash;
  bool ok = false;
  bool skipped = false;      ///< not stored: this run found it done
  std::string error;         ///< why it failed (the assessment's message, or the trial's problem)
  double seconds = 0;
  double max_rss_mb = 0;     ///< peak memory of the assessment process
  nlohmann::json summary;    ///< the trial's figures (null when failed)
  nlohmann::json to_json() const;
  static JobRecord from_json(const nlohmann::json& j);
};

/// OUT/jobs/<trial id>.
std::filesystem::path job_dir(const RunContext& context, const Trial& trial);

/// SHA-256 (hex) over clearfit's version, the job's manifest entries and the
/// bytes of its input files (scene, captures, calibration). Empty when an
/// input cannot be read (the job then fails with the reason).
std::string job_hash(const Manifest& manifest, std::size_t index, const RunContext& context, std::string* error = nullptr);

/// Runs job `index` (skipped when its record is ok with the same hash).
/// Never throws for a trial's own problems: they are in the record.
JobRecord run_job(const Manifest& manifest, std::size_t index, const RunContext& context);

struct PoolProgress {
  std::size_t done = 0, total = 0, skipped = 0, failed = 0, running = 0;
  double elapsed_s = 0, eta_s = -1;  ///< −1: not known yet
  std::string last;                  ///< the trial that just finished
};

/// Runs every job with `jobs` in parallel; `progress` after each.
std::vector<JobRecord> run_jobs(const Manifest& manifest, const RunContext& context, int jobs,
                                const std::function<void(const PoolProgress&)>& progress = {});

/// The record of job `index` as stored (failed with "not run" when there is none).
JobRecord read_job_record(const Manifest& manifest, std::size_t index, const RunContext& context);

}  // namespace clearfit::study
