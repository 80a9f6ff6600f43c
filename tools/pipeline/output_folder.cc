#include "tools/pipeline/output_folder.h"

#include <unistd.h>

#include <system_error>

#include "core/error.h"
#include "core/io/atomic_write.h"

namespace bodymodel {

namespace fs = std::filesystem;

void refuse_existing_output(const fs::path& dir, bool force, const std::string& force_option) {
  std::error_code ec;
  if (fs::exists(dir, ec) && !force)
    throw InputError("output folder '" + dir.string() + "' already exists (use " + force_option +
                     " to replace it)");
}

StagedFolder::StagedFolder(fs::path final_dir, bool force, const std::string& force_option)
    : final_(std::move(final_dir)) {
  // "out/" → "out": the staging name is built from the last component.
  if (final_.filename().empty()) final_ = final_.parent_path();
  if (final_.empty()) throw InputError("empty output folder name");
  refuse_existing_output(final_, force, force_option);
  std::error_code ec;
  if (fs::exists(final_, ec) && !fs::is_directory(final_, ec))
    throw InputError("output '" + final_.string() + "' exists and is not a folder");
  const fs::path parent = final_.has_parent_path() ? final_.parent_path() : fs::path(".");
  ensure_directory(parent);
  staging_ = parent / ("." + final_.filename().string() + ".partial-" + std::to_string(::getpid()));
  fs::remove_all(staging_, ec);
  ensure_directory(staging_);
}

StagedFolder::~StagedFolder() {
  if (committed_) return;
  std::error_code ec;
  fs::remove_all(staging_, ec);
}

void StagedFolder::commit() {
  std::error_code ec;
  fs::path old;
  if (fs::exists(final_, ec)) {
    old = final_.parent_path() / ("." + final_.filename().string() + ".old-" + std::to_string(::getpid()));
    fs::remove_all(old, ec);
    fs::rename(final_, old, ec);
    if (ec) throw InputError("cannot replace '" + final_.string() + "': " + ec.message());
  }
  fs::rename(staging_, final_, ec);
  if (ec) {
    if (!old.empty()) fs::rename(old, final_, ec);
    throw InputError("cannot move the finished output into '" + final_.string() + "': " + ec.message());
  }
  committed_ = true;
  if (!old.empty()) fs::remove_all(old, ec);
}

}  // namespace bodymodel
