// Where the shared data sets live: $BODYMODEL_DATA, else ../shared/data beside the repository.
#pragma once

#include <filesystem>

namespace bodymodel {

// The data root. Throws InputError naming the folder if it does not exist.
std::filesystem::path data_root();

// data_root() / relative, checked to exist (InputError otherwise).
std::filesystem::path data_file(const std::filesystem::path& relative);

}  // namespace bodymodel
