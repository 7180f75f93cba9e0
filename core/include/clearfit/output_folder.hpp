#pragma once
// Output folders that are never half-written: a command writes into a staging
// folder beside the target and swaps it in when everything is written. At every
// moment the target holds either the complete old folder or the complete new
// one, also when the process is killed (SIGKILL, power loss aside):
//  - the swap is one atomic renameat2(RENAME_EXCHANGE) of the staging folder
//    with the old one, after which the old one (now under the staging name) is
//    removed; where the file system cannot exchange, the old folder is renamed
//    to ".NAME.old-PID" first and put back by the next run if it was killed
//    between the two renames;
//  - staging and old folders left by killed runs (their PID is gone) are
//    removed by the next run that writes the same target.
#include <filesystem>
#include <vector>

namespace clearfit {

/// For tests of crash safety: when the environment variable
/// CLEARFIT_TEST_PAUSE_AT equals `stage`, the process stops itself (SIGSTOP)
/// there, so a test can kill it at exactly that point. Stages: "staged" (the
/// staging folder exists), "written" (everything is in it), "swapped" (the new
/// folder is in place, the old not yet removed), "file-written" (an atomic file
/// write before its rename).
void pause_point(const char* stage);

/// Throws InputError naming `path` when the folder it goes into does not exist
/// (unless `may_create` and every missing folder can be created: the nearest
/// existing one is a folder) or is a file.
void check_output_folder(const std::filesystem::path& path, bool may_create = false);

/// Creates the missing folders above `path`; returns the ones created,
/// outermost first (for removal when the command fails). InputError on failure.
std::vector<std::filesystem::path> create_output_folders(const std::filesystem::path& path);

/// Removes staging and old folders of `target` left by runs that were killed,
/// and puts an old folder back when a killed run left no folder at `target`.
void recover_output_folder(const std::filesystem::path& target);

/// Removes the temporary files of write_file_atomically(`target`) left by
/// runs that were killed before their rename.
void remove_stale_temporaries(const std::filesystem::path& target);

class StagedFolder {
 public:
  /// Recovers what killed runs left (recover_output_folder), creates the
  /// target's parent folders and an empty staging folder beside the target.
  /// `keep_contents`: the staging folder starts with (hard links to) the old
  /// folder's files, for commands that add to a folder. InputError when the
  /// target is a file, the current folder or one above it.
  explicit StagedFolder(std::filesystem::path target, bool keep_contents = false);
  /// Removes the staging folder (and the parent folders it created) unless committed.
  ~StagedFolder();
  StagedFolder(const StagedFolder&) = delete;
  StagedFolder& operator=(const StagedFolder&) = delete;

  /// Where to write.
  const std::filesystem::path& path() const { return staging_; }
  /// Puts the staging folder in place of the target (see above).
  void commit();

 private:
  void discard();  // removes the staging folder and the folders created, unless committed
  std::filesystem::path target_, staging_;
  std::vector<std::filesystem::path> created_;
  bool committed_ = false;
};

}  // namespace clearfit
