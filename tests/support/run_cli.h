// Runs the bodymodel executable in tests and captures its output and exit code.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace bodymodel::fixtures {

struct CliResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

// `args` is appended to the executable path and run through the shell (quote as needed);
// `env` (e.g. "BODYMODEL_DATA=/x") is put in front of the command.
inline CliResult run_cli(const std::string& args, const std::string& env = "") {
  std::string cmd = env + (env.empty() ? "" : " ") + "'" + BODYMODEL_EXE + "' " + args + " 2>&1";
  CliResult r;
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), pipe)) > 0) r.output.append(buf.data(), n);
  int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

// The same, for tests written as `EXPECT_EQ(run_cli(args, &output), 0)`.
inline int run_cli(const std::string& args, std::string* output) {
  CliResult r = run_cli(args);
  *output = std::move(r.output);
  return r.exit_code;
}

}  // namespace bodymodel::fixtures
