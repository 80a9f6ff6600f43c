// The settings record of a resumable output folder: one mechanism for every verb that fills its
// folder item by item and skips finished items on a rerun (`generate`, `crowd`, `register`,
// `register-mesh`, `skin apply`; `synth-db` keeps its database.json the same way).
//
// The verb records in OUT/<record> (JSON) every setting that changes what an item's files hold,
// with its input files named by a content fingerprint (file_fingerprint), not by path, so the
// record holds no folder of the machine and a moved input still resumes. A rerun:
//   - into a missing folder, or one holding none of the verb's outputs: a fresh start;
//   - with the same settings: resumes (finished items are kept);
//   - with other settings, an unreadable record, or outputs but no record (an older bodymodel):
//     refused with one line naming the folder and the first setting that differs, unless
//     --force, which removes the earlier outputs and starts afresh.
// Nothing is written until open(): a command refused for another reason (bad option, unreadable
// input) leaves the folder as it was.
#pragma once

#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>

namespace bodymodel {

// "" when `file` holds the JSON object `expected`; otherwise what differs first: "no
// generate.json", "generate.json does not parse", "seed was 11, now 12", "quick not recorded".
std::string settings_difference(const std::filesystem::path& file, const nlohmann::json& expected);

// A content fingerprint of a file ("crc32 <8 hex digits>, <bytes> bytes"); InputError naming the
// file when it cannot be read.
std::string file_fingerprint(const std::filesystem::path& path);

class ResumableFolder {
 public:
  // `is_output(name)`: whether a top-level entry of the folder (file or folder name) is one of
  // this verb's outputs (removed when the folder is replaced; their presence without a record
  // is refused). Reads the record; writes nothing. Throws InputError when refused (see above).
  ResumableFolder(std::filesystem::path dir, std::string record, nlohmann::json settings, bool force,
                  std::function<bool(const std::string& name)> is_output);

  // True when the folder holds items made with these same settings, which the verb keeps.
  bool resumes() const { return resume_; }
  // Whether the folder already held outputs (of any settings) when the command started.
  bool had_outputs() const { return had_outputs_; }
  // What differed from the record ("" for a new folder or the same settings).
  const std::string& difference() const { return difference_; }

  // Creates the folder; unless resuming (or with allow_resume false), removes the record and
  // the earlier outputs first, then writes the record. Returns resumes() && allow_resume.
  bool open(bool allow_resume = true);

  const std::filesystem::path& path() const { return dir_; }

 private:
  std::filesystem::path dir_;
  std::string record_;
  nlohmann::json settings_;
  std::function<bool(const std::string&)> is_output_;
  bool resume_ = false, had_outputs_ = false;
  std::string difference_;
};

// is_output helpers: names ending in one of `suffixes`, or equal to one of `names`.
std::function<bool(const std::string&)> outputs_named(std::vector<std::string> names,
                                                      std::vector<std::string> suffixes = {});

}  // namespace bodymodel
