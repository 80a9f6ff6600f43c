// An output folder written as a whole: a verb writes into a hidden staging folder beside the
// final one, and the staging folder replaces the final one only when everything is written
// (commit). A failure (bad input, disk full, a crash) therefore never leaves a half-written
// output under the final name, and an existing folder is refused unless the user forces it.
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

  // Replaces `final_dir` (an existing one is removed only now) by the staging folder.
  void commit();

 private:
  std::filesystem::path final_, staging_;
  bool committed_ = false;
};

// Throws InputError when `dir` exists and `force` is false (the check StagedFolder makes). Verbs
// that fill a folder incrementally and resume record their settings instead
// (tools/pipeline/folder_settings.h).
void refuse_existing_output(const std::filesystem::path& dir, bool force, const std::string& force_option = "--force");

}  // namespace bodymodel
