#include "core/data_path.h"

#include <cstdlib>

#include "core/error.h"

namespace bodymodel {

std::filesystem::path data_root() {
  const char* env = std::getenv("BODYMODEL_DATA");
  std::filesystem::path root = (env && *env) ? std::filesystem::path(env)
                                             : std::filesystem::path(BODYMODEL_DEFAULT_DATA);
  std::error_code ec;
  if (!std::filesystem::is_directory(root, ec))
    throw InputError("data folder '" + root.string() +
                     "' does not exist: set BODYMODEL_DATA to the folder holding makehuman/ "
                     "and animations/");
  return std::filesystem::weakly_canonical(root, ec);
}

std::filesystem::path data_file(const std::filesystem::path& relative) {
  auto p = data_root() / relative;
  std::error_code ec;
  if (!std::filesystem::exists(p, ec))
    throw InputError("data file '" + p.string() + "' is missing (BODYMODEL_DATA = " +
                     data_root().string() + ")");
  return p;
}

}  // namespace bodymodel
