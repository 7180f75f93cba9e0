#pragma once
// A study as a Slurm job array: one array task per trial, each calling the
// same per-job entry point as the local pool (`clearfit study job MANIFEST
// --index $SLURM_ARRAY_TASK_ID --out OUT`), then one reduce job that starts
// after every task has ended (`--dependency=afterany`) and writes the tables.
#include <clearfit/study/jobs.hpp>

#include <filesystem>
#include <optional>
#include <string>

namespace clearfit::study {

struct SlurmOptions {
  std::string partition;            ///< empty: the cluster's default
  std::string time_limit = "01:00:00";  ///< per task (HH:MM:SS)
  int memory_mb = 4096;             ///< per task
  int cpus_per_task = 2;
  int max_parallel = 0;             ///< array throttle (%N); 0: no limit
  std::string account;              ///< empty: the user's default
  void validate() const;            ///< throws std::invalid_argument naming the field
};

struct SlurmFiles {
  std::filesystem::path array_script, reduce_script, submit_script;
};

/// Writes OUT/slurm/{array.sbatch, reduce.sbatch, submit.sh}. submit.sh submits
/// the array, then the reduce job depending on it, and prints both job ids.
/// Paths in the scripts are absolute (the cluster's nodes must see the same
/// file system paths: the manifest's inputs, the output folder and the
/// clearfit executable).
SlurmFiles write_slurm_scripts(const Manifest& manifest, const RunContext& context, const SlurmOptions& options);

}  // namespace clearfit::study
