// An output folder written as a whole: a verb writes into a hidden staging folder beside the
// final one, and the staging folder replaces the final one only when everything is written
// (commit). A failure (bad input, disk full, a crash) therefore never leaves a half-written
// output under the final name, and an existing folder is refused unless the user forces it.
// A folder that appears under the final name while the run writes (another run, a user's file)
// is never replaced: the commit checks again and moves without replacing.
#pragma once

#include <filesystem>
#include <string>

namespace bodymodel {

class StagedFolder {
 public:
  // Refuses (InputError, one line naming the folder and the option) when `final_dir` exists and
  // `force` is false; creates the parent and the staging folder (InputError naming the folder
  // when that fails or it is not writable). `force_option` is the flag named in the message.
  // Staging folders of `final_dir` left by runs that have ended (killed or interrupted) are
  // removed; those of a running process are kept.
  StagedFolder(std::filesystem::path final_dir, bool force, const std::string& force_option = "--force");
  // Removes the staging folder unless committed.
  ~StagedFolder();
  StagedFolder(const StagedFolder&) = delete;
  StagedFolder& operator=(const StagedFolder&) = delete;

  // Where to write now (the staging folder).
  const std::filesystem::path& path() const { return staging_; }
  const std::filesystem::path& final_path() const { return final_; }
  // staging / name
  std::filesystem::path operator/(const std::filesystem::path& name) const { return staging_ / name; }

  // Moves the staging folder to `final_dir`. A folder there that existed at construction (and
  // was forced) is replaced, and removed only now. One that appeared since is left alone:
  // InputError naming it and where this run's finished output was kept instead
  // ("<final>.new-PID", beside it).
  void commit();

 private:
  std::filesystem::path final_, staging_;
  bool existed_ = false;  // final_ existed at construction (so it was forced)
  bool committed_ = false;
};

// Renames `from` to `to` unless `to` exists (renameat2 RENAME_NOREPLACE where the file system
// has it; elsewhere rename(), which replaces at most an empty folder). false with errno EEXIST
// or ENOTEMPTY when `to` exists; false with another errno on other failures.
bool rename_no_replace(const std::filesystem::path& from, const std::filesystem::path& to);

// Throws InputError when `dir` exists and `force` is false (the check StagedFolder makes). Verbs
// that fill a folder incrementally and resume record their settings instead
// (tools/pipeline/folder_settings.h).
void refuse_existing_output(const std::filesystem::path& dir, bool force, const std::string& force_option = "--force");

}  // namespace bodymodel
