#include "markers/marker_data.h"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "core/error.h"
#include "markers/c3d.h"
#include "markers/trc.h"

namespace bodymodel {

void check_marker_data(const MarkerData& d, const std::string& source) {
  if (!std::isfinite(d.rate) || d.rate <= 0)
    throw InputError(source + ": the frame rate must be a positive number, found " + std::to_string(d.rate));
  if (d.xyz.cols() != 3 * static_cast<Eigen::Index>(d.labels.size()))
    throw InputError(source + ": " + std::to_string(d.labels.size()) + " labels but " +
                     std::to_string(d.xyz.cols()) + " coordinate columns");
  for (size_t m = 0; m < d.labels.size(); ++m) {
    const std::string& l = d.labels[m];
    if (l.empty() || l.find_first_of("\t\r\n") != std::string::npos)
      throw InputError(source + ": marker " + std::to_string(m + 1) + " has an empty label or one holding a tab or line end");
  }
  for (Eigen::Index f = 0; f < d.xyz.rows(); ++f)
    for (Eigen::Index m = 0; m < static_cast<Eigen::Index>(d.labels.size()); ++m) {
      const int nan = std::isnan(d.xyz(f, 3 * m)) + std::isnan(d.xyz(f, 3 * m + 1)) + std::isnan(d.xyz(f, 3 * m + 2));
      const bool finite = d.xyz.block<1, 3>(f, 3 * m).allFinite();
      if (!(nan == 3 || (nan == 0 && finite)))
        throw InputError(source + ": frame " + std::to_string(f + 1) + " marker '" + d.labels[m] +
                         "': a sample must be three finite numbers or missing");
    }
}

double millimetres_per_unit(const std::string& unit, const std::string& source) {
  std::string u;
  for (char c : unit)
    if (!std::isspace(static_cast<unsigned char>(c))) u += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (u.empty() || u == "mm") return 1;
  if (u == "cm") return 10;
  if (u == "m") return 1000;
  throw InputError(source + ": unknown length unit '" + unit + "' (expected mm, cm or m)");
}

namespace {
std::string lower_extension(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  return e;
}
}  // namespace

MarkerData read_markers(const std::filesystem::path& path) {
  const std::string e = lower_extension(path);
  if (e == ".c3d") return read_c3d(path);
  if (e == ".trc") return read_trc(path);
  throw InputError(path.string() + ": a marker file must be .c3d or .trc");
}

void write_markers(const std::filesystem::path& path, const MarkerData& d) {
  const std::string e = lower_extension(path);
  if (e == ".c3d") return write_c3d(path, d);
  if (e == ".trc") return write_trc(path, d);
  throw InputError(path.string() + ": a marker file must be .c3d or .trc");
}

double missing_fraction(const MarkerData& d) {
  const Eigen::Index n = d.xyz.rows() * static_cast<Eigen::Index>(d.labels.size());
  if (n == 0) return 0;
  Eigen::Index missing = 0;
  for (Eigen::Index f = 0; f < d.xyz.rows(); ++f)
    for (int m = 0; m < d.marker_count(); ++m) missing += !d.present(static_cast<int>(f), m);
  return double(missing) / double(n);
}

}  // namespace bodymodel
