// Where the bodymodel executable is, for CLI tests. Force-included into every test source
// (see tests/CMakeLists.txt) so that `BODYMODEL_EXE` works as before.
//
// Why not a -D with the absolute path: that path differs between checkouts, which made every
// test object miss ccache in a fresh clone. The path is resolved at run time instead:
// $BODYMODEL_EXE if set (CTest sets it), else `../bodymodel` next to the test binary's folder.
#pragma once

#include <string>

namespace bodymodel::fixtures {
std::string bodymodel_exe();  // defined in tests/test_main.cc
}  // namespace bodymodel::fixtures

#define BODYMODEL_EXE (::bodymodel::fixtures::bodymodel_exe())
