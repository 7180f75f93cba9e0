// clearfit study run|job|reduce|slurm MANIFEST: many participants × conditions
// × trials as independent jobs (study/), locally or as a Slurm array.
#include <clearfit/cli/commands.hpp>

#include <clearfit/error.hpp>
#include <clearfit/format.hpp>
#include <clearfit/study/jobs.hpp>
#include <clearfit/study/slurm.hpp>
#include <clearfit/study/tables.hpp>

#include <unistd.h>

#include <cmath>
#include <iostream>
#include <thread>

namespace clearfit::cli {
namespace {

namespace fs = std::filesystem;

struct StudyOpts {
  std::string manifest, out;
  int jobs = 1;
  std::size_t index = 0;
  bool quiet = false, submit = false;
  study::SlurmOptions slurm;
};

study::RunContext context_for(const StudyOpts& o) {
  return {fs::read_symlink("/proc/self/exe"), o.out, CLEARFIT_VERSION};
}

std::string minutes(double s) {
  if (s < 0) return "?";
  return s < 90 ? fixed_digits(s, 0) + " s" : fixed_digits(s / 60, 1) + " min";
}

/// Prints the tables' summary; exit 0 when every job is ok, else 2.
int report(const study::StudyTables& t, const fs::path& out) {
  for (const auto& f : t.summary["failed"])
    std::cerr << "clearfit: trial " << f["trial"].get<std::string>() << " failed: " << f["error"].get<std::string>() << "\n";
  const auto& reg = t.summary["regression"];
  std::cout << "study: " << t.ok << " of " << t.ok + t.failed << " trials ok";
  if (reg["participants"].get<int>() > 0)
    std::cout << "; colour change vs pressure over " << reg["participants"] << " participants: mean R² "
              << reg["mean_r2"].dump() << " (study 0.439), significant at 5 % " << reg["significant_5pct"] << ", at 10 % "
              << reg["significant_10pct"];
  std::cout << "\nwrote " << (out / "study.json").string() << " and the tables beside it\n";
  if (t.failed > 0) {
    std::cerr << "clearfit: error: " << t.failed << " trial(s) failed (listed above and in " << (out / "trials.csv").string()
              << "); the others are in the tables. Fix them and run again: finished trials are skipped\n";
    return 2;
  }
  return 0;
}

int run_study(const StudyOpts& o) {
  const study::Manifest m = study::read_manifest(o.manifest);
  const study::RunContext ctx = context_for(o);
  const int jobs = o.jobs > 0 ? o.jobs : static_cast<int>(std::max(1u, std::thread::hardware_concurrency() / 2));
  if (!o.quiet)
    std::cerr << "study " << m.study << ": " << m.trials.size() << " trials, " << jobs << " at a time, into " << o.out << "\n";
  study::run_jobs(m, ctx, jobs, [&](const study::PoolProgress& p) {
    if (o.quiet) return;
    std::cerr << "\r\033[K" << p.done << "/" << p.total << " done (" << p.skipped << " skipped, " << p.failed << " failed), "
              << p.running << " running, " << minutes(p.elapsed_s) << " elapsed, ETA " << minutes(p.eta_s) << " — " << p.last
              << (p.done == p.total ? "\n" : "") << std::flush;
  });
  return report(study::reduce_study(m, ctx), o.out);
}

int run_one_job(const StudyOpts& o) {
  const study::Manifest m = study::read_manifest(o.manifest);
  if (o.index >= m.trials.size())
    throw InputError(o.manifest, "trials", "--index " + std::to_string(o.index) + " is past the last trial (" +
                                               std::to_string(m.trials.size()) + " trials, indices from 0)");
  const study::JobRecord r = study::run_job(m, o.index, context_for(o));
  std::cout << "trial " << r.trial << ": " << (r.skipped ? "already done" : r.ok ? "ok" : "failed") << "\n";
  if (!r.ok) std::cerr << "clearfit: error: trial " << r.trial << ": " << r.error << "\n";
  return r.ok ? 0 : 2;
}

int write_slurm(const StudyOpts& o) {
  const study::Manifest m = study::read_manifest(o.manifest);
  study::SlurmOptions s = o.slurm;
  try {
    s.validate();
  } catch (const std::invalid_argument& e) {
    throw InputError("", "option", e.what(), "see clearfit study slurm --help");
  }
  const study::SlurmFiles f = study::write_slurm_scripts(m, context_for(o), s);
  std::cout << "wrote " << f.array_script.string() << " (" << m.trials.size() << " array tasks), "
            << f.reduce_script.string() << " and " << f.submit_script.string() << "\n";
  if (!o.submit) {
    std::cout << "submit with: " << f.submit_script.string() << "\n";
    return 0;
  }
  const int rc = std::system(f.submit_script.c_str());
  if (rc != 0) throw InputError(f.submit_script.string(), "", "sbatch failed (exit " + std::to_string(rc) + ")",
                                "check that Slurm's sbatch is on PATH and the options fit the cluster");
  return 0;
}

Run add_study(CLI::App& app) {
  auto o = std::make_shared<StudyOpts>();
  CLI::App* study = app.add_subcommand("study", "Many participants × conditions × trials: run, resume, tables, Slurm");
  study->require_subcommand(1);
  auto common = [&](CLI::App* s) {
    s->add_option("MANIFEST", o->manifest, "Study manifest (YAML, schema clearfit.study/1)")->required();
    s->add_option("--out", o->out, "The study's output folder (jobs/, tables)")->required();
  };
  CLI::App* run = study->add_subcommand("run", "Run every trial (skipping finished ones), then write the tables");
  common(run);
  run->add_option("--jobs", o->jobs, "Trials assessed at once (0: half the cores)")->capture_default_str()->check(CLI::NonNegativeNumber);
  run->add_flag("--quiet", o->quiet, "No progress line");
  CLI::App* job = study->add_subcommand("job", "Run one trial (the entry point of a Slurm array task)");
  common(job);
  job->add_option("--index", o->index, "The trial's index in the manifest, from 0")->required();
  CLI::App* reduce = study->add_subcommand("reduce", "Write the tables from the finished jobs");
  common(reduce);
  CLI::App* slurm = study->add_subcommand("slurm", "Write an sbatch job array (one task per trial) and its reduce job");
  common(slurm);
  slurm->add_option("--partition", o->slurm.partition, "Slurm partition (default: the cluster's)");
  slurm->add_option("--account", o->slurm.account, "Slurm account (default: the user's)");
  slurm->add_option("--time", o->slurm.time_limit, "Time limit per task")->capture_default_str();
  slurm->add_option("--mem-mb", o->slurm.memory_mb, "Memory per task, MB")->capture_default_str();
  slurm->add_option("--cpus", o->slurm.cpus_per_task, "CPUs per task")->capture_default_str();
  slurm->add_option("--max-parallel", o->slurm.max_parallel, "At most this many tasks at once (0: no limit)")->capture_default_str();
  slurm->add_flag("--submit", o->submit, "Also submit it (sbatch)");
  return [o, run, job, reduce, slurm]() {
    if (run->parsed()) return run_study(*o);
    if (job->parsed()) return run_one_job(*o);
    if (slurm->parsed()) return write_slurm(*o);
    (void)reduce;
    const study::Manifest m = study::read_manifest(o->manifest);
    return report(study::reduce_study(m, context_for(*o)), o->out);
  };
}

static const Registration registered{"study", 85, add_study};

}  // namespace
}  // namespace clearfit::cli
