#include "population/ansur.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>

#include "core/error.h"
#include "core/io/csv.h"

namespace bodymodel {

namespace {

bool parse_number(const std::string& s, double& v) {
  if (s.empty()) return false;
  char* end = nullptr;
  v = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size() && std::isfinite(v);
}

// The human range of a column in its file unit (weightkg in kilograms, after conversion).
std::pair<double, double> human_range(const std::string& column) {
  if (column == "stature") return {1000, 2500};
  if (column == "weightkg") return {25, 300};
  if (column == "Age") return {15, 90};
  if (column == "DODRace" || column == "SubjectNumericRace" || column == "Heightin" || column == "Weightlbs")
    return {-1e9, 1e9};  // codes and self-reported values: taken as they are
  return {1, 3000};      // lengths, breadths, depths and girths in mm
}

}  // namespace

int AnsurTable::column(const std::string& name) const {
  const auto it = std::find(columns.begin(), columns.end(), name);
  if (it == columns.end()) {
    std::string known;
    for (size_t i = 0; i < columns.size() && i < 8; ++i) known += (i ? ", " : "") + columns[i];
    throw InputError(fmt::format("'{}': no column '{}' (ANSUR II's columns: {}, …)", source.string(), name, known));
  }
  return int(it - columns.begin());
}

AnsurTable read_ansur(const std::filesystem::path& path, const std::vector<std::string>& required) {
  const std::vector<CsvRecord> rows = read_csv_file(path);
  if (rows.size() < 2) throw InputError(fmt::format("'{}': no rows below the header", path.string()));
  const std::vector<std::string>& header = rows[0].fields;
  auto find = [&](const std::string& name) {
    return int(std::find(header.begin(), header.end(), name) - header.begin());
  };
  // The published files differ: the men's says "subjectid", the women's "SubjectId".
  int id_col = int(header.size());
  for (size_t c = 0; c < header.size(); ++c) {
    std::string h = header[c];
    for (char& ch : h) ch = char(std::tolower(static_cast<unsigned char>(ch)));
    if (h == "subjectid") id_col = int(c);
  }
  const int sex_col = find("Gender");
  if (id_col == int(header.size()) || sex_col == int(header.size()))
    throw InputError(fmt::format("'{}': not an ANSUR II file (no 'subjectid' or 'Gender' column)", path.string()));
  for (const auto& r : required)
    if (find(r) == int(header.size()))
      throw InputError(fmt::format("'{}': no column '{}' (renamed or missing; ANSUR II names it so)", path.string(), r));
  AnsurTable t;
  t.source = path;
  // The numeric columns: those that parse on the first data row (the required ones must).
  std::vector<int> cols;
  for (size_t c = 0; c < header.size(); ++c) {
    double v;
    const bool wanted = std::find(required.begin(), required.end(), header[c]) != required.end();
    if (int(c) != id_col && (wanted || (c < rows[1].fields.size() && parse_number(rows[1].fields[c], v)))) {
      cols.push_back(int(c));
      t.columns.push_back(header[c]);
    }
  }
  t.values.resize(Eigen::Index(rows.size() - 1), Eigen::Index(cols.size()));
  for (size_t r = 1; r < rows.size(); ++r) {
    const CsvRecord& rec = rows[r];
    if (rec.fields.size() != header.size())
      throw InputError(fmt::format("'{}' line {}: {} cells for {} columns", path.string(), rec.line, rec.fields.size(),
                                   header.size()));
    t.ids.push_back(rec.fields[id_col]);
    const std::string& sex = rec.fields[sex_col];
    if (sex != "Male" && sex != "Female")
      throw InputError(fmt::format("'{}' line {}, column 'Gender': expected Male or Female, found '{}'", path.string(),
                                   rec.line, sex));
    t.male.push_back(sex == "Male");
    for (size_t k = 0; k < cols.size(); ++k) {
      double v;
      if (!parse_number(rec.fields[cols[k]], v))
        throw InputError(fmt::format("'{}' line {}, column '{}': '{}' is not a number", path.string(), rec.line,
                                     t.columns[k], rec.fields[cols[k]]));
      t.values(Eigen::Index(r - 1), Eigen::Index(k)) = v;
    }
  }
  // Weight: tenths of a kilogram in the survey's files; a column already in kilograms would make
  // every body a tenth of its weight.
  const auto w = std::find(t.columns.begin(), t.columns.end(), "weightkg");
  if (w != t.columns.end()) {
    const Eigen::Index c = w - t.columns.begin();
    if (t.values.col(c).maxCoeff() <= 300)
      throw InputError(fmt::format("'{}', column 'weightkg': every value is at most 300, as if in kilograms; ANSUR II "
                                   "writes tenths of a kilogram (e.g. 815 for 81.5 kg)",
                                   path.string()));
    t.values.col(c) /= 10.0;
  }
  for (Eigen::Index c = 0; c < t.values.cols(); ++c) {
    const auto [lo, hi] = human_range(t.columns[size_t(c)]);
    for (Eigen::Index r = 0; r < t.values.rows(); ++r)
      if (t.values(r, c) < lo || t.values(r, c) > hi)
        throw InputError(fmt::format("'{}' line {}, column '{}': {} is outside a human range ({} … {}{})",
                                     path.string(), rows[size_t(r) + 1].line, t.columns[size_t(c)], t.values(r, c), lo,
                                     hi, t.columns[size_t(c)] == "weightkg" ? " kg" : ""));
  }
  return t;
}

bool is_ansur_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  if (!in || !std::getline(in, line)) return false;
  if (line.rfind("\xEF\xBB\xBF", 0) == 0) line = line.substr(3);
  const std::string first = line.substr(0, line.find(','));
  return first == "subjectid" || first == "SubjectId" || first == "\"subjectid\"" || first == "\"SubjectId\"";
}

}  // namespace bodymodel
