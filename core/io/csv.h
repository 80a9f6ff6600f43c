// Comma-separated rows as the project writes and reads them: no quoting (no field of ours holds
// a comma), a trailing CR or spaces of a cell dropped, a trailing comma an empty last cell.
#pragma once

#include <string>
#include <vector>

namespace bodymodel {

std::vector<std::string> split_csv_line(const std::string& line);

}  // namespace bodymodel
