// The viewer's static files (tools/viewer/index.html, viewer.js), compiled into the executable
// by CMake (a generated .cc with their text), so `bodymodel viewer` needs no source tree.
#pragma once

namespace bodymodel::cli {
const char* viewer_index_html();
const char* viewer_js();
const char* serve_html();   // `bodymodel serve`'s page
}  // namespace bodymodel::cli
