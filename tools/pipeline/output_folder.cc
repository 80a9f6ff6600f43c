#include "tools/pipeline/output_folder.h"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
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
