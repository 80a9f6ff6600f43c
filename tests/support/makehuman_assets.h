// The data's MakeHuman folder when it has the assets (clothes, hair, proxies), else empty: the
// dressed-character tests skip, saying why, without them.
#pragma once

#include <exception>
#include <filesystem>

#include "core/data_path.h"

namespace bodymodel::fixtures {

inline std::filesystem::path makehuman_with_assets() {
  std::filesystem::path dir;
  try {
    dir = data_root() / "makehuman";
  } catch (const std::exception&) {
    return {};
  }
  return std::filesystem::is_directory(dir / "assets") ? dir : std::filesystem::path();
}

}  // namespace bodymodel::fixtures
