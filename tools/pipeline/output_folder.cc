#include "tools/pipeline/output_folder.h"

#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <vector>

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

namespace {

// Removes the staging (".<name>.partial-PID") and replaced (".<name>.old-PID") folders beside
// `final_dir` that processes which have ended left behind (killed, or interrupted: the signal
// handler removes open temporaries, not folders). A live process's folders are kept.
void remove_ended_runs(const fs::path& parent, const std::string& name) {
  std::error_code ec;
  std::vector<fs::path> ended;
  for (auto it = fs::directory_iterator(parent, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string n = it->path().filename().string();
    for (const std::string tag : {".partial-", ".old-"}) {
      const std::string prefix = "." + name + tag;
      if (n.size() <= prefix.size() || n.compare(0, prefix.size(), prefix) != 0) continue;
      const std::string digits = n.substr(prefix.size());
      if (digits.find_first_not_of("0123456789") != std::string::npos || digits.size() > 9) continue;
      const long pid = std::stol(digits);
      if (pid == ::getpid()) continue;
      if (::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) ended.push_back(it->path());
    }
  }
  for (const auto& p : ended) fs::remove_all(p, ec);
}

}  // namespace

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
  remove_ended_runs(parent, final_.filename().string());
  existed_ = fs::exists(final_, ec);
  staging_ = parent / ("." + final_.filename().string() + ".partial-" + std::to_string(::getpid()));
  fs::remove_all(staging_, ec);
  ensure_directory(staging_);
}

StagedFolder::~StagedFolder() {
  if (committed_) return;
  std::error_code ec;
  fs::remove_all(staging_, ec);
}

bool rename_no_replace(const fs::path& from, const fs::path& to) {
#ifdef RENAME_NOREPLACE
  if (::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), RENAME_NOREPLACE) == 0) return true;
  // Not supported by the kernel or this file system: rename() below.
  if (errno != EINVAL && errno != ENOSYS && errno != ENOTSUP) return false;
#endif
  std::error_code ec;
  if (fs::exists(to, ec)) {
    errno = EEXIST;
    return false;
  }
  // rename() replaces an empty folder only: a folder with anything in it fails (ENOTEMPTY).
  return ::rename(from.c_str(), to.c_str()) == 0;
}

void StagedFolder::commit() {
  std::error_code ec;
  const fs::path parent = final_.has_parent_path() ? final_.parent_path() : fs::path(".");
  fs::path old;
  if (existed_ && fs::exists(final_, ec)) {
    old = parent / ("." + final_.filename().string() + ".old-" + std::to_string(::getpid()));
    fs::remove_all(old, ec);
    fs::rename(final_, old, ec);
    if (ec) throw InputError("cannot replace '" + final_.string() + "': " + ec.message());
  }
  if (rename_no_replace(staging_, final_)) {
    committed_ = true;
    if (!old.empty()) fs::remove_all(old, ec);
    return;
  }
  const int err = errno;
  if (!old.empty()) rename_no_replace(old, final_);  // put the forced folder back if nothing took its place
  if (err != EEXIST && err != ENOTEMPTY)
    throw InputError("cannot move the finished output into '" + final_.string() + "': " + std::strerror(err));
  // Something appeared under the final name during the run: it is not ours to replace. The
  // finished output stays, under a name that says what it is.
  const fs::path kept = parent / (final_.filename().string() + ".new-" + std::to_string(::getpid()));
  if (rename_no_replace(staging_, kept)) {
    committed_ = true;  // nothing left to clean up
    throw InputError("output folder '" + final_.string() +
                     "' appeared while this run was writing (another run or program made it); it was left "
                     "alone, and this run's output is in '" + kept.string() + "'");
  }
  throw InputError("output folder '" + final_.string() +
                   "' appeared while this run was writing (another run or program made it); it was left alone "
                   "and this run's output was discarded");
}

}  // namespace bodymodel
