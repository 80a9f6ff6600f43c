#include "tools/console.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>

namespace bodymodel::cli {

ProgressBar::ProgressBar(std::string label)
    : label_(std::move(label)),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_ - std::chrono::seconds(1)),
      tty_(isatty(fileno(stderr))) {}

ProgressBar::~ProgressBar() {
  if (!finished_ && tty_ && last_percent_ >= 0) std::fprintf(stderr, "\n");
}

void ProgressBar::update(double fraction, std::string_view what) {
  fraction = std::clamp(fraction, 0.0, 1.0);
  auto now = std::chrono::steady_clock::now();
  int percent = static_cast<int>(std::floor(fraction * 100));
  if (tty_) {
    if (now - last_draw_ < std::chrono::milliseconds(100) && fraction < 1.0) return;
  } else if (percent / 10 == last_percent_ / 10 && fraction < 1.0) {
    return;  // log files get a line every 10 %
  }
  last_draw_ = now;
  last_percent_ = percent;
  double elapsed = std::chrono::duration<double>(now - start_).count();
  double eta = fraction > 1e-6 ? elapsed * (1 - fraction) / fraction : 0;
  const int width = 30;
  int filled = static_cast<int>(fraction * width);
  std::string bar(filled, '#');
  bar.resize(width, '.');
  std::string w(what.substr(0, 40));
  if (tty_)
    std::fprintf(stderr, "\r%s [%s] %3d%% %6.1fs ETA %6.1fs %-40s", label_.c_str(), bar.c_str(),
                 percent, elapsed, eta, w.c_str());
  else
    std::fprintf(stderr, "%s [%s] %3d%% %.1fs ETA %.1fs %s\n", label_.c_str(), bar.c_str(),
                 percent, elapsed, eta, w.c_str());
  std::fflush(stderr);
}

void ProgressBar::finish(std::string_view message) {
  if (finished_) return;
  finished_ = true;
  double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  std::string m(message);
  if (tty_) std::fprintf(stderr, "\r\033[K");
  std::fprintf(stderr, "%s done in %.1fs%s%s\n", label_.c_str(), elapsed, m.empty() ? "" : ": ",
               m.c_str());
}

ProgressCallback ProgressBar::callback() {
  return [this](double f, std::string_view what) {
    update(f, what);
    return true;
  };
}

std::vector<std::string> split_commas(std::string_view list) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start <= list.size()) {
    size_t end = list.find(',', start);
    if (end == std::string_view::npos) end = list.size();
    if (end > start) out.emplace_back(list.substr(start, end - start));
    start = end + 1;
  }
  return out;
}

void info(std::string_view message) {
  std::fprintf(stderr, "bodymodel: %.*s\n", static_cast<int>(message.size()), message.data());
}
void warn(std::string_view message) {
  std::fprintf(stderr, "bodymodel: warning: %.*s\n", static_cast<int>(message.size()),
               message.data());
}

}  // namespace bodymodel::cli
