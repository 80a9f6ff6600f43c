// fmt for the model library in header-only mode: the stage libraries do not link fmt (only
// the command line does), and this keeps message formatting readable without touching the
// top-level CMakeLists.txt.
#pragma once

#ifndef FMT_HEADER_ONLY
#define FMT_HEADER_ONLY
#endif
#include <fmt/format.h>
