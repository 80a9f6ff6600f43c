#include "core/io/csv.h"

namespace bodymodel {

std::vector<std::string> split_csv_line(const std::string& line) {
  std::vector<std::string> out;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    std::string cell = line.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    while (!cell.empty() && (cell.back() == '\r' || cell.back() == ' ')) cell.pop_back();
    if (comma == std::string::npos) {
      if (!cell.empty() || !out.empty() || !line.empty()) out.push_back(std::move(cell));
      return out;
    }
    out.push_back(std::move(cell));
    start = comma + 1;
  }
}

}  // namespace bodymodel
