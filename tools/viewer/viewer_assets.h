// The viewer's static files (tools/viewer/index.html, viewer.js), compiled into the executable
// by CMake (a generated .cc with their text), so `bodymodel viewer` needs no source tree.
#pragma once

#include <cstdlib>
#include <filesystem>

namespace bodymodel::cli {
const char* viewer_index_html();
const char* viewer_js();
const char* serve_html();   // `bodymodel serve`'s page

// three.min.js to copy or serve: $BODYMODEL_THREE, else the build folder's npm install
// (scripts/setup.sh; BODYMODEL_BUILD_DIR is compiled into the executable).
inline std::filesystem::path default_three_js() {
  if (const char* e = std::getenv("BODYMODEL_THREE"); e && *e) return e;
#ifdef BODYMODEL_BUILD_DIR
  return std::filesystem::path(BODYMODEL_BUILD_DIR) / "npm" / "node_modules" / "three" / "build" / "three.min.js";
#else
  return {};
#endif
}
}  // namespace bodymodel::cli
