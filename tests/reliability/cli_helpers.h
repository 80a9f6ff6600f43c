// Helpers of the reliability CLI tests: run the bodymodel tool (in the foreground or as a child
// to interrupt), find leftover temporaries, check that written files are complete.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "core/error.h"
#include "support/input_error.h"
#include "core/io/atomic_write.h"

namespace bodymodel::reliability {

namespace fs = std::filesystem;

// A child process running `bodymodel args...` with stdout+stderr to `log`.
struct Child {
  pid_t pid = -1;
  int status = 0;
  // Waits for the end; true when it ended by signal `sig` (or exited 128 + sig).
  bool ended_by(int sig) {
    waitpid(pid, &status, 0);
    return (WIFSIGNALED(status) && WTERMSIG(status) == sig) ||
           (WIFEXITED(status) && WEXITSTATUS(status) == 128 + sig);
  }
  int exit_code() {
    waitpid(pid, &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
};

inline Child spawn_bodymodel(const std::vector<std::string>& args, const fs::path& log) {
  const std::string exe = BODYMODEL_EXE;
  std::vector<std::string> all{exe};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  Child c;
  c.pid = fork();
  if (c.pid == 0) {
    const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      dup2(fd, 1);
      dup2(fd, 2);
    }
    execv(exe.c_str(), argv.data());
    _exit(127);
  }
  return c;
}

// Runs to the end; exit code, output in *out.
inline int run_bodymodel(const std::vector<std::string>& args, const fs::path& log, std::string* out) {
  Child c = spawn_bodymodel(args, log);
  const int code = c.exit_code();
  *out = read_text_file(log);
  return code;
}

// Polls every 10 ms until pred() or the timeout; returns pred().
inline bool wait_until(const std::function<bool()>& pred, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!pred()) {
    if (std::chrono::steady_clock::now() > end) return pred();
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

inline std::vector<fs::path> files_under(const fs::path& dir) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::end(it); it.increment(ec)) {
    std::error_code entry;  // a symlink loop is no regular file (and must not throw here)
    if (it->is_regular_file(entry)) out.push_back(it->path());
  }
  return out;
}

// write_atomically temporaries (".<name>.tmp<pid>_<n>") anywhere under dir.
inline std::vector<fs::path> temporaries_under(const fs::path& dir) {
  std::vector<fs::path> out;
  for (const auto& p : files_under(dir)) {
    const std::string n = p.filename().string();
    if (n.size() > 1 && n[0] == '.' && n.find(".tmp") != std::string::npos) out.push_back(p);
  }
  return out;
}

// Every regular file under `dir` (relative path → bytes): two folders are identical when these are.
inline std::map<std::string, std::string> folder_contents(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& p : files_under(dir)) out[fs::relative(p, dir).string()] = read_text_file(p);
  return out;
}

// "" when `a` and `b` hold the same files with the same bytes; otherwise the first difference.
inline std::string folder_difference(const fs::path& a, const fs::path& b) {
  const auto fa = folder_contents(a), fb = folder_contents(b);
  for (const auto& [name, bytes] : fa) {
    auto it = fb.find(name);
    if (it == fb.end()) return name + " only in " + a.string();
    if (it->second != bytes) return name + " differs";
  }
  for (const auto& [name, bytes] : fb)
    if (!fa.count(name)) return name + " only in " + b.string();
  return "";
}

inline std::string message_of(const std::function<void()>& f) { return testing::input_error_of(f); }

// Lines of `text` that start with "bodymodel: error:".
inline std::vector<std::string> error_lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (line.rfind("bodymodel: error:", 0) == 0) out.push_back(line);
  return out;
}

}  // namespace bodymodel::reliability
