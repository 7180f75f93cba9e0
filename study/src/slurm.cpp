#include <clearfit/error.hpp>
#include <clearfit/study/slurm.hpp>

#include "files.hpp"

#include <sys/stat.h>

#include <fstream>
#include <regex>
#include <stdexcept>

namespace clearfit::study {
namespace {

namespace fs = std::filesystem;

/// A path quoted for sh.
std::string sh(const fs::path& p) {
  std::string s = "'";
  for (char c : p.string()) s += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return s + "'";
}

std::string header(const std::string& name, const SlurmOptions& o, const fs::path& logs) {
  std::string h = "#!/bin/bash\n#SBATCH --job-name=" + name + "\n#SBATCH --time=" + o.time_limit +
                  "\n#SBATCH --mem=" + std::to_string(o.memory_mb) + "M\n#SBATCH --cpus-per-task=" +
                  std::to_string(o.cpus_per_task) + "\n";
  if (!o.partition.empty()) h += "#SBATCH --partition=" + o.partition + "\n";
  if (!o.account.empty()) h += "#SBATCH --account=" + o.account + "\n";
  return h + "#SBATCH --chdir=" + logs.string() + "\n";
}

}  // namespace

void SlurmOptions::validate() const {
  static const std::regex time(R"((\d+-)?\d{1,2}:\d{2}:\d{2})"), name(R"([A-Za-z0-9_.-]*)");
  if (!std::regex_match(time_limit, time))
    throw std::invalid_argument("time_limit = '" + time_limit + "': expected HH:MM:SS or D-HH:MM:SS");
  if (memory_mb < 64) throw std::invalid_argument("memory_mb = " + std::to_string(memory_mb) + ": must be at least 64");
  if (cpus_per_task < 1) throw std::invalid_argument("cpus_per_task = " + std::to_string(cpus_per_task) + ": must be at least 1");
  if (max_parallel < 0) throw std::invalid_argument("max_parallel = " + std::to_string(max_parallel) + ": must be ≥ 0");
  if (!std::regex_match(partition, name)) throw std::invalid_argument("partition = '" + partition + "': letters, digits, _ . - only");
  if (!std::regex_match(account, name)) throw std::invalid_argument("account = '" + account + "': letters, digits, _ . - only");
}

SlurmFiles write_slurm_scripts(const Manifest& m, const RunContext& context, const SlurmOptions& o) {
  o.validate();
  const fs::path out = fs::absolute(context.out), dir = out / "slurm", logs = dir / "logs";
  fs::create_directories(logs);
  const fs::path exe = fs::absolute(context.clearfit_exe), manifest = fs::absolute(m.path);
  const std::string name = std::regex_replace(m.study, std::regex("[^A-Za-z0-9_.-]"), "_");
  SlurmFiles f{dir / "array.sbatch", dir / "reduce.sbatch", dir / "submit.sh"};
  std::string array = header(name, o, logs) + "#SBATCH --array=0-" + std::to_string(m.trials.size() - 1) +
                      (o.max_parallel > 0 ? "%" + std::to_string(o.max_parallel) : "") +
                      "\n#SBATCH --output=job-%a.log\n# One trial of the study per array task (clearfit study job).\nexec " +
                      sh(exe) + " study job " + sh(manifest) + " --index \"$SLURM_ARRAY_TASK_ID\" --out " + sh(out) + "\n";
  std::string reduce = header(name + "-reduce", o, logs) +
                       "#SBATCH --output=reduce.log\n# The tables of the study once every task has ended.\nexec " + sh(exe) +
                       " study reduce " + sh(manifest) + " --out " + sh(out) + "\n";
  std::string submit = "#!/bin/bash\n# Submits the study's array, then its reduce step (after every task, ok or not).\n"
                       "set -euo pipefail\narray=$(sbatch --parsable " + sh(f.array_script) + ")\narray=${array%%;*}\n"
                       "reduce=$(sbatch --parsable --dependency=afterany:$array " + sh(f.reduce_script) + ")\n"
                       "echo \"array $array reduce ${reduce%%;*}\"\n";
  write_text_atomically(f.array_script, array, true);
  write_text_atomically(f.reduce_script, reduce, true);
  write_text_atomically(f.submit_script, submit, true);
  return f;
}

}  // namespace clearfit::study
