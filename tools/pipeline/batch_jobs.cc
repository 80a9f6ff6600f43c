#include "tools/pipeline/batch_jobs.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <mutex>
#include <numeric>

#include "core/error.h"
#include "tools/console.h"

namespace bodymodel {

BatchJobs::BatchJobs(BatchSpec spec, std::vector<std::string> names, std::vector<std::string> shown)
    : spec_(std::move(spec)), names_(std::move(names)), shown_(std::move(shown)) {
  if (spec_.workers < 1) throw InputError("--jobs must be at least 1, got " + std::to_string(spec_.workers));
  if (shown_.empty()) shown_ = names_;
  todo_.resize(names_.size());
  std::iota(todo_.begin(), todo_.end(), size_t(0));
}

size_t BatchJobs::skip_done(const std::function<bool(size_t)>& done, const std::string& folder) {
  std::vector<size_t> left;
  for (size_t k : todo_)
    if (spec_.force || !done(k)) left.push_back(k);
  if (left.size() < todo_.size())
    cli::info(fmt::format("{} of {} {} already {} in {}: skipped", todo_.size() - left.size(), todo_.size(),
                          spec_.items, spec_.done_verb, folder));
  todo_ = std::move(left);
  return todo_.size();
}

int BatchJobs::run(const std::string& label, const Job& job) {
  cli::ProgressBar bar(label);
  std::mutex mutex;  // guards the bar, `current`, the counts and the console lines
  int done = 0;
  const size_t n = todo_.size();
  std::vector<double> current(n, 0.0);  // per job, in [0, 1]
  auto update = [&](const std::string& what) {
    double f = 0;
    for (double c : current) f += c;
    bar.update(f / n, what);
  };
  tbb::task_arena arena(spec_.workers);
  arena.execute([&] {
    // Grain 1: each job is long (seconds to minutes), so every item is its own task.
    tbb::parallel_for(size_t(0), n, size_t(1), [&](size_t j) {
      const size_t k = todo_[j];
      const std::string& name = names_[k];
      try {
        const std::string note = job(k, [&, j](double f) {
          std::lock_guard<std::mutex> lock(mutex);
          current[j] = f;
          update(name);
        });
        std::lock_guard<std::mutex> lock(mutex);
        if (!note.empty()) cli::info(note);
        current[j] = 1.0;
        ++done;
        update(name);
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> lock(mutex);
        current[j] = 1.0;
        failures_.push_back(name + ": " + e.what());
        cli::warn(fmt::format("{} {} failed and was skipped: {}", spec_.item, shown_[k], e.what()));
      }
    });
  });
  bar.finish(fmt::format("{} {}, {} failed", done, spec_.done_verb, failures_.size()));
  return done;
}

void BatchJobs::throw_if_failed() const {
  if (!failures_.empty())
    throw InputError(fmt::format("{} of {} {} failed; first: {}", failures_.size(), todo_.size(), spec_.items,
                                 failures_.front()));
}

}  // namespace bodymodel
