#include <clearfit/error.hpp>
#include <clearfit/study/jobs.hpp>

#include "files.hpp"
#include "process.hpp"
#include "trial_summary.hpp"

#include <openssl/evp.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <fstream>
#include <memory>
#include <mutex>
#include <thread>

namespace clearfit::study {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

/// Incremental SHA-256 (OpenSSL EVP).
class Sha256 {
 public:
  Sha256() : ctx_(EVP_MD_CTX_new(), EVP_MD_CTX_free) { EVP_DigestInit_ex(ctx_.get(), EVP_sha256(), nullptr); }
  void add(const std::string& s) { EVP_DigestUpdate(ctx_.get(), s.data(), s.size()); }
  /// Adds a file's bytes, or a folder's regular files (names and bytes, in name order).
  bool add_path(const fs::path& p) {
    std::error_code ec;
    if (fs::is_directory(p, ec)) {
      std::vector<fs::path> files;
      for (const auto& e : fs::directory_iterator(p, ec))
        if (e.is_regular_file()) files.push_back(e.path());
      std::sort(files.begin(), files.end());
      for (const auto& f : files) {
        add(f.filename().string());
        if (!add_path(f)) return false;
      }
      return !ec;
    }
    std::ifstream in(p, std::ios::binary);
    if (!in) return false;
    std::vector<char> buffer(1 << 20);
    while (in) {
      in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
      EVP_DigestUpdate(ctx_.get(), buffer.data(), static_cast<std::size_t>(in.gcount()));
    }
    return in.eof();
  }
  std::string hex() {
    unsigned char md[EVP_MAX_MD_SIZE];
    unsigned int n = 0;
    EVP_DigestFinal_ex(ctx_.get(), md, &n);
    static const char* digits = "0123456789abcdef";
    std::string s;
    for (unsigned int i = 0; i < n; ++i) s += {digits[md[i] >> 4], digits[md[i] & 15]};
    return s;
  }

 private:
  std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> ctx_;
};

std::vector<std::pair<std::string, fs::path>> job_inputs(const Manifest& m, const Trial& t) {
  std::vector<std::pair<std::string, fs::path>> in{{"scene", m.condition(t.condition).scene}};
  if (!t.both.empty()) in.emplace_back("capture", t.both);
  if (!t.baseline.empty()) in.emplace_back("baseline", t.baseline);
  if (!t.worn.empty()) in.emplace_back("worn", t.worn);
  if (const auto& cal = m.participant(t.participant).calibration) in.emplace_back("calibration", *cal);
  return in;
}

json job_spec(const Manifest& m, const Trial& t, const std::string& version) {
  const Condition& c = m.condition(t.condition);
  const Participant& p = m.participant(t.participant);
  json j{{"version", version}, {"trial", t.id}, {"participant", p.id}, {"person", p.person}, {"condition", c.id},
         {"pressure", m.analysis.pressure}, {"window_frames", m.analysis.window_frames},
         {"profile", {m.analysis.profile.length_mm, m.analysis.profile.angle_step_deg, m.analysis.profile.sample_mm}}};
  if (t.force_n) j["force_n"] = *t.force_n;
  if (c.bump) {
    j["bump"] = {c.bump->diameter_mm, c.bump->height_mm};
    if (c.bump->centre_mm) j["bump_centre"] = {c.bump->centre_mm->x(), c.bump->centre_mm->y()};
  }
  return j;
}

std::vector<std::string> assess_arguments(const Manifest& m, const Trial& t, const fs::path& assessment) {
  const Condition& c = m.condition(t.condition);
  std::vector<std::string> args{"assess", c.scene.string(), "--out", assessment.string(), "--no-html", "--quiet"};
  if (!t.both.empty()) args.insert(args.end(), {"--both", t.both.string()});
  else args.insert(args.end(), {"--baseline", t.baseline.string(), "--worn", t.worn.string()});
  const Participant& p = m.participant(t.participant);
  if (p.calibration && m.analysis.pressure)
    args.insert(args.end(), {"--calibration", p.calibration->string(), "--person", p.person});
  if (m.analysis.window_frames > 0) args.insert(args.end(), {"--window-frames", std::to_string(m.analysis.window_frames)});
  return args;
}

/// The last non-empty line of a log that starts with "clearfit: " (the error), else its last line.
std::string error_from_log(const fs::path& log) {
  std::ifstream in(log);
  std::string line, last, last_error;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    last = line;
    if (line.rfind("clearfit: error", 0) == 0 || line.rfind("clearfit: ", 0) == 0) last_error = line;
  }
  return last_error.empty() ? last : last_error;
}

JobRecord failed_record(const Trial& t, std::size_t index, std::string hash, std::string error) {
  JobRecord r;
  r.trial = t.id;
  r.index = index;
  r.hash = std::move(hash);
  r.error = std::move(error);
  return r;
}

JobRecord execute(const Manifest& m, std::size_t index, const RunContext& context, const std::string& hash) {
  const Trial& t = m.trials[index];
  JobRecord r = failed_record(t, index, hash, "");
  const fs::path dir = job_dir(context, t);
  fs::create_directories(dir);
  const auto start = std::chrono::steady_clock::now();
  const ProcessResult p = run_process(context.clearfit_exe, assess_arguments(m, t, dir / "assessment"), dir / "assess.log");
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.max_rss_mb = p.max_rss_mb;
  if (p.exit_code != 0) {
    r.error = "clearfit assess exited " + std::to_string(p.exit_code) + ": " + error_from_log(dir / "assess.log");
    return r;
  }
  try {
    r.summary = summarise_trial(m, t, dir / "assessment");
    r.ok = true;
  } catch (const std::exception& e) {
    r.error = std::string("summary: ") + e.what();
  }
  return r;
}

}  // namespace

json JobRecord::to_json() const {
  return {{"schema", "clearfit.study-job/1"}, {"trial", trial}, {"index", index}, {"hash", hash},
          {"status", ok ? "ok" : "failed"}, {"error", error}, {"seconds", seconds}, {"max_rss_mb", max_rss_mb},
          {"summary", summary}};
}

JobRecord JobRecord::from_json(const json& j) {
  JobRecord r;
  r.trial = j.at("trial").get<std::string>();
  r.index = j.at("index").get<std::size_t>();
  r.hash = j.at("hash").get<std::string>();
  r.ok = j.at("status").get<std::string>() == "ok";
  r.error = j.at("error").get<std::string>();
  r.seconds = j.at("seconds").get<double>();
  r.max_rss_mb = j.value("max_rss_mb", 0.0);
  r.summary = j.at("summary");
  return r;
}

fs::path job_dir(const RunContext& context, const Trial& trial) { return context.out / "jobs" / trial.id; }

std::string job_hash(const Manifest& m, std::size_t index, const RunContext& context, std::string* error) {
  const Trial& t = m.trials.at(index);
  Sha256 sha;
  sha.add(job_spec(m, t, context.version).dump());
  for (const auto& [role, path] : job_inputs(m, t)) {
    sha.add(role);
    if (!sha.add_path(path)) {
      if (error) *error = path.string() + ": the " + role + " cannot be read (" +
                          (fs::exists(path) ? "permission or read error" : "no such file") + ")";
      return {};
    }
  }
  return sha.hex();
}

JobRecord read_job_record(const Manifest& m, std::size_t index, const RunContext& context) {
  const Trial& t = m.trials.at(index);
  const JobRecord none = failed_record(t, index, "", "not run");
  if (!t.problem.empty()) return none;
  std::ifstream in(job_dir(context, t) / "job.json");
  if (!in) return none;
  try {
    JobRecord r = JobRecord::from_json(json::parse(in));
    return r.trial == t.id ? r : none;
  } catch (const std::exception&) {
    return none;
  }
}

/// Writes the job's record (last, atomically).
static void store(const JobRecord& r, const RunContext& context, const Trial& t) {
  write_text_atomically(job_dir(context, t) / "job.json", r.to_json().dump(2) + "\n");
}

JobRecord run_job(const Manifest& m, std::size_t index, const RunContext& context) {
  const Trial& t = m.trials.at(index);
  if (!t.problem.empty()) return failed_record(t, index, "", m.path.filename().string() + ": " + t.problem);
  std::string why;
  const std::string hash = job_hash(m, index, context, &why);
  if (hash.empty()) {  // an input cannot be read: recorded, so the tables say why
    const JobRecord r = failed_record(t, index, "", why);
    fs::remove_all(job_dir(context, t));
    fs::create_directories(job_dir(context, t));
    store(r, context, t);
    return r;
  }
  JobRecord stored = read_job_record(m, index, context);
  if (stored.ok && stored.hash == hash) {
    stored.skipped = true;
    return stored;
  }
  fs::remove_all(job_dir(context, t));
  JobRecord r = execute(m, index, context, hash);
  store(r, context, t);
  return r;
}

std::vector<JobRecord> run_jobs(const Manifest& m, const RunContext& context, int jobs,
                                const std::function<void(const PoolProgress&)>& progress) {
  const std::size_t n = m.trials.size();
  std::vector<JobRecord> records(n);
  std::atomic<std::size_t> next{0};
  std::mutex mutex;
  PoolProgress state;
  state.total = n;
  double run_seconds = 0;
  std::size_t ran = 0;
  const auto start = std::chrono::steady_clock::now();
  auto worker = [&] {
    for (std::size_t i; (i = next++) < n;) {
      {
        std::lock_guard lock(mutex);
        ++state.running;
      }
      JobRecord r = run_job(m, i, context);
      std::lock_guard lock(mutex);
      --state.running;
      ++state.done;
      state.skipped += r.skipped;
      state.failed += !r.ok;
      if (!r.skipped && r.ok) {
        run_seconds += r.seconds;
        ++ran;
      }
      state.last = r.trial;
      state.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      const std::size_t left = n - state.done;
      state.eta_s = ran > 0 ? run_seconds / ran * static_cast<double>(left) / std::max(1, jobs) : -1;
      records[i] = std::move(r);
      if (progress) progress(state);
    }
  };
  std::vector<std::thread> pool;
  for (int k = 0; k < std::max(1, jobs); ++k) pool.emplace_back(worker);
  for (auto& th : pool) th.join();
  return records;
}

}  // namespace clearfit::study
