// Headless Chromium and three.js for the browser tests: where they are (Debian's chromium,
// scripts/setup.sh's pinned three.js; BODYMODEL_CHROMIUM and BODYMODEL_THREE override), and the
// DOM of a page after it ran with software GL. Tests skip, saying why, when either is missing.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace bodymodel::fixtures {

inline std::string chromium_path() {
  if (const char* c = std::getenv("BODYMODEL_CHROMIUM"); c && *c) return c;
  return "/usr/bin/chromium";
}

inline std::filesystem::path three_dir() {
  if (const char* t = std::getenv("BODYMODEL_THREE"); t && *t) return t;
  return std::filesystem::absolute("npm/node_modules/three");  // the build folder's (tests run from it)
}

// The DOM of `url` (a file:// URL, query allowed) after it ran; virtual_time_ms > 0 runs the page
// on virtual time for that long (0: a real clock, for pages that time their frames).
inline std::string headless_dom(const std::string& url, int virtual_time_ms = 30000) {
  const std::string cmd = "'" + chromium_path() +
                          "' --headless=new --no-sandbox --disable-gpu --use-angle=swiftshader "
                          "--enable-unsafe-swiftshader --allow-file-access-from-files " +
                          (virtual_time_ms > 0 ? "--virtual-time-budget=" + std::to_string(virtual_time_ms) + " " : "") +
                          "--dump-dom '" + url + "' 2>/dev/null";
  std::string dom;
  if (FILE* p = popen(cmd.c_str(), "r")) {
    char buf[4096];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, p)) > 0) dom.append(buf, n);
    pclose(p);
  }
  return dom;
}

}  // namespace bodymodel::fixtures
