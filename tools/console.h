// Terminal output for the command line (library code never prints; the tools do).
#pragma once

#include <chrono>
#include <string>
#include <string_view>
#include <vector>

#include "core/progress.h"

namespace bodymodel::cli {

// A one-line progress bar with ETA on stderr (plain lines when stderr is not a terminal).
class ProgressBar {
 public:
  explicit ProgressBar(std::string label);
  ~ProgressBar();
  void update(double fraction, std::string_view what = {});
  void finish(std::string_view message = {});
  // A ProgressCallback that feeds this bar (never cancels).
  ProgressCallback callback();

 private:
  std::string label_;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
  bool tty_;
  bool finished_ = false;
  int last_percent_ = -1;
};

// "a,b,,c" → {"a", "b", "c"}: a comma-separated option value, empty items dropped.
std::vector<std::string> split_commas(std::string_view list);

// Informational line on stderr ("bodymodel: ..."), so stdout stays machine-readable.
void info(std::string_view message);
void warn(std::string_view message);

}  // namespace bodymodel::cli
