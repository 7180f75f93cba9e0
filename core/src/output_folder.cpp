#include <clearfit/output_folder.hpp>
#include <clearfit/error.hpp>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <string>
#include <unistd.h>

namespace clearfit {
namespace fs = std::filesystem;

namespace {

fs::path parent_of(const fs::path& p) { return p.parent_path().empty() ? fs::path(".") : p.parent_path(); }

std::string hidden_name(const fs::path& target, const char* kind, long pid) {
  return "." + target.filename().string() + "." + kind + "-" + std::to_string(pid);
}

// The PID in "<prefix><digits>", or -1.
long pid_after(const std::string& name, const std::string& prefix) {
  if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) return -1;
  const std::string digits = name.substr(prefix.size());
  if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) return -1;
  return std::stol(digits);
}

bool alive(long pid) { return pid == ::getpid() || ::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM; }

// Exchanges two paths atomically; false when the file system cannot.
bool exchange(const fs::path& a, const fs::path& b) {
#ifdef RENAME_EXCHANGE
  if (::renameat2(AT_FDCWD, a.c_str(), AT_FDCWD, b.c_str(), RENAME_EXCHANGE) == 0) return true;
  if (errno != EINVAL && errno != ENOSYS && errno != ENOTSUP)
    throw InputError(b.string(), "", std::string("cannot put the new outputs in place: ") + std::strerror(errno));
#endif
  return false;
}

}  // namespace

void pause_point(const char* stage) {
  const char* at = std::getenv("CLEARFIT_TEST_PAUSE_AT");
  if (at && std::strcmp(at, stage) == 0) std::raise(SIGSTOP);
}

void check_output_folder(const fs::path& path, bool may_create) {
  if (path.empty()) return;
  fs::path p = path.parent_path();
  std::error_code ec;
  while (!p.empty() && !fs::exists(p, ec)) {
    if (!may_create) throw InputError(path.string(), "", "the folder " + p.string() + " does not exist", "create it first");
    p = p.parent_path();
  }
  if (!p.empty() && !fs::is_directory(p, ec))
    throw InputError(path.string(), "", p.string() + " is a file, not a folder", "choose an output path in a folder");
}

std::vector<fs::path> create_output_folders(const fs::path& path) {
  check_output_folder(path, true);
  std::vector<fs::path> missing;
  std::error_code ec;
  for (fs::path p = path.parent_path(); !p.empty() && !fs::exists(p, ec); p = p.parent_path()) missing.insert(missing.begin(), p);
  for (const auto& p : missing)
    if (!fs::create_directory(p, ec) && ec)
      throw InputError(path.string(), "", "cannot create the folder " + p.string() + ": " + ec.message(), "check the path and its permissions");
  return missing;
}

void recover_output_folder(const fs::path& target) {
  const fs::path parent = parent_of(target);
  const std::string partial = "." + target.filename().string() + ".partial-", old = "." + target.filename().string() + ".old-";
  std::error_code ec;
  std::vector<fs::path> olds, leftovers;
  for (fs::directory_iterator it(parent, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const long p = pid_after(name, partial), o = pid_after(name, old);
    if (p > 0 && !alive(p)) leftovers.push_back(it->path());
    if (o > 0 && !alive(o)) olds.push_back(it->path());
  }
  for (const auto& o : olds) {
    // Killed between its two renames: the old folder is the last complete one.
    if (!fs::exists(target, ec)) fs::rename(o, target, ec);
    else leftovers.push_back(o);
  }
  for (const auto& l : leftovers) fs::remove_all(l, ec);
}

void remove_stale_temporaries(const fs::path& target) {
  const std::string prefix = "." + target.stem().string() + ".tmp", ext = target.extension().string();
  std::error_code ec;
  std::vector<fs::path> stale;
  for (fs::directory_iterator it(parent_of(target), ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind(prefix, 0) != 0 || name.size() < prefix.size() + ext.size() || name.compare(name.size() - ext.size(), ext.size(), ext) != 0)
      continue;
    const std::string middle = name.substr(prefix.size(), name.size() - prefix.size() - ext.size());  // PID_N
    const auto underscore = middle.find('_');
    if (underscore == std::string::npos || middle.find_first_not_of("0123456789", underscore + 1) != std::string::npos) continue;
    const long pid = pid_after(middle.substr(0, underscore), "");
    if (pid > 0 && !alive(pid)) stale.push_back(it->path());
  }
  for (const auto& f : stale) fs::remove(f, ec);
}

StagedFolder::StagedFolder(fs::path target, bool keep_contents) : target_(std::move(target)) {
  if (target_.empty()) throw InputError("", "output folder", "is empty");
  target_ = target_.lexically_normal();
  if (!target_.has_filename()) target_ = target_.parent_path();  // "a/b/" is "a/b"
  std::error_code ec;
  const fs::path here = fs::current_path(ec), full = fs::weakly_canonical(fs::absolute(target_), ec);
  const auto rel = here.lexically_relative(full);
  if (full == full.root_path() || (!rel.empty() && *rel.begin() != ".."))
    throw InputError(target_.string(), "", "is the current folder or one above it; the outputs would replace it",
                     "give a folder of its own for the outputs");
  if (fs::exists(target_, ec) && !fs::is_directory(target_, ec))
    throw InputError(target_.string(), "", "is a file, expected a folder for the outputs", "give another output folder");
  created_ = create_output_folders(target_);
  recover_output_folder(target_);
  staging_ = parent_of(target_) / hidden_name(target_, "partial", ::getpid());
  fs::remove_all(staging_, ec);
  if (keep_contents && fs::is_directory(target_, ec)) fs::copy(target_, staging_, fs::copy_options::recursive, ec);
  else fs::create_directory(staging_, ec);
  if (ec) {
    const std::string why = ec.message();
    discard();
    throw InputError(target_.string(), "", "cannot create the staging folder " + staging_.string() + ": " + why,
                     "check the folder's permissions and free space");
  }
  pause_point("staged");
}

StagedFolder::~StagedFolder() { discard(); }

void StagedFolder::discard() {
  if (committed_) return;
  std::error_code ignored;
  if (!staging_.empty()) fs::remove_all(staging_, ignored);
  for (auto it = created_.rbegin(); it != created_.rend(); ++it) fs::remove(*it, ignored);  // only if empty
  created_.clear();
  staging_.clear();
}

void StagedFolder::commit() {
  pause_point("written");
  std::error_code ec;
  if (fs::exists(target_, ec) && exchange(staging_, target_)) {
    // The new folder is in place; the old one is under the staging name.
    committed_ = true;
    pause_point("swapped");
    fs::remove_all(staging_, ec);
    return;
  }
  const fs::path old = parent_of(target_) / hidden_name(target_, "old", ::getpid());
  if (fs::exists(target_, ec)) {
    fs::rename(target_, old, ec);  // a kill from here to the next rename: recover_output_folder() puts it back
    if (ec) throw InputError(target_.string(), "", "cannot move the old outputs aside: " + ec.message());
    pause_point("swapped");
  }
  fs::rename(staging_, target_, ec);
  if (ec) {
    std::error_code ignored;
    fs::rename(old, target_, ignored);
    throw InputError(target_.string(), "", "cannot put the new outputs in place: " + ec.message());
  }
  committed_ = true;
  fs::remove_all(old, ec);
}

}  // namespace clearfit
