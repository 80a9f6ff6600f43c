// Progress reporting from library code without printing: a callback the caller implements
// (the command line turns it into a progress bar).
#pragma once

#include <functional>
#include <string_view>

namespace bodymodel {

// Called with the fraction done in [0, 1] and a short description of the current step.
// Return false to ask the algorithm to stop early (it then throws bodymodel::Cancelled).
using ProgressCallback = std::function<bool(double fraction, std::string_view what)>;

struct Cancelled : std::exception {
  const char* what() const noexcept override { return "cancelled"; }
};

// Reports through `cb` if it is set; throws Cancelled if the callback asks to stop.
inline void report_progress(const ProgressCallback& cb, double fraction, std::string_view what) {
  if (cb && !cb(fraction, what)) throw Cancelled{};
}

}  // namespace bodymodel
