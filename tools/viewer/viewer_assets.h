// The viewer's static files (tools/viewer/index.html, viewer.js), compiled into the executable
// by CMake (a generated .cc with their text), so `bodymodel viewer` needs no source tree.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <string>

namespace bodymodel::cli {
const char* viewer_index_html();
const char* viewer_js();
const char* serve_html();   // `bodymodel serve`'s page
const char* crowd_viewer_html();   // the crowd viewer `crowd --outfits` writes (crowd.html)

// three.min.js to copy or serve: $BODYMODEL_THREE, else the build folder's npm install
// (scripts/setup.sh). The build folder's path lives in the generated viewer_assets.cc only, so
// the other sources compile the same in every clone and a fresh clone still hits ccache.
const char* build_dir();
inline std::filesystem::path default_three_js() {
  if (const char* e = std::getenv("BODYMODEL_THREE"); e && *e) return e;
  return std::filesystem::path(build_dir()) / "npm" / "node_modules" / "three" / "build" / "three.min.js";
}
// Base64 of raw bytes: the viewer and serve ship vertex arrays inside scripts (file:// pages
// cannot fetch binary files).
inline std::string base64(const void* data, size_t n) {
  static const char* tab = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const auto* p = static_cast<const unsigned char*>(data);
  std::string s;
  s.reserve((n + 2) / 3 * 4);
  for (size_t i = 0; i < n; i += 3) {
    unsigned v = p[i] << 16 | (i + 1 < n ? p[i + 1] << 8 : 0) | (i + 2 < n ? p[i + 2] : 0);
    s += tab[v >> 18 & 63];
    s += tab[v >> 12 & 63];
    s += i + 1 < n ? tab[v >> 6 & 63] : '=';
    s += i + 2 < n ? tab[v & 63] : '=';
  }
  return s;
}
}  // namespace bodymodel::cli
