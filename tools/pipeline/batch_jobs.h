// The loop of the batch verbs (`register`, `register-mesh`): items whose outputs already exist
// are skipped (a rerun or another shard resumes), the rest run as jobs on J workers with one
// progress line over all of them, and a job that throws is reported and recorded without
// stopping the others; the verb fails (InputError, exit 2) at the end if any did.
//
// Interrupts need nothing here: main() installs the handler that removes the temporaries of
// the files being written (core/io/interrupt_cleanup.h), and every output is written
// atomically, so a finished item is complete and an unfinished one is redone on the rerun.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace bodymodel {

struct BatchSpec {
  std::string item = "item", items = "items";  // nouns of the messages: "scan", "scans"
  std::string done_verb = "done";              // "3 registered, 1 failed"
  int workers = 1;                             // jobs run in parallel (≥ 1)
  bool force = false;                          // run items that are already done again
};

class BatchJobs {
 public:
  // One item per name (names identify items in the progress line and the failure list);
  // `shown`, if given, names them in the failure warnings instead (e.g. the input path).
  BatchJobs(BatchSpec spec, std::vector<std::string> names, std::vector<std::string> shown = {});

  // Drops the items `done(k)` reports complete (unless spec.force) and says how many were
  // skipped ("2 of 5 scans already registered in OUT: skipped"). Returns the items left.
  size_t skip_done(const std::function<bool(size_t k)>& done, const std::string& folder);
  size_t pending() const { return todo_.size(); }

  // A job: item k (index into the names), reporting its own progress in [0, 1]. It returns an
  // informational line printed when it succeeds (empty: none) and throws to fail.
  using Job = std::function<std::string(size_t k, const std::function<void(double)>& progress)>;
  // Runs every pending item under the progress line `label`; returns how many succeeded.
  int run(const std::string& label, const Job& job);

  // "name: message" per failed item, in the order they failed.
  const std::vector<std::string>& failures() const { return failures_; }
  // InputError "F of N scans failed; first: ..." when any job failed.
  void throw_if_failed() const;

 private:
  BatchSpec spec_;
  std::vector<std::string> names_, shown_;
  std::vector<size_t> todo_;
  std::vector<std::string> failures_;
};

}  // namespace bodymodel
