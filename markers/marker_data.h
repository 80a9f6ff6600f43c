// Marker captures in memory, and their files (C3D: markers/c3d.h, TRC: markers/trc.h).
// A capture is a set of named 3-D trajectories sampled at one rate; a sample that the system did
// not see is NaN (C3D marks it with a residual word of -1, TRC with empty fields).
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <limits>
#include <filesystem>
#include <string>
#include <vector>

namespace bodymodel {

struct MarkerData {
  std::vector<std::string> labels;  // one per marker; Vicon names unlabelled pieces "*1", "*2", …
  double rate = 100;                // frames per second
  int first_frame = 1;              // number of the first frame (C3D header, TRC Frame#)
  Eigen::MatrixXd xyz;              // frames × 3·markers, millimetres; NaN = missing sample

  int frame_count() const { return static_cast<int>(xyz.rows()); }
  int marker_count() const { return static_cast<int>(labels.size()); }
  bool present(int f, int m) const { return !std::isnan(xyz(f, 3 * m)); }
  Eigen::Vector3d at(int f, int m) const { return xyz.block<1, 3>(f, 3 * m).transpose(); }
  void set(int f, int m, const Eigen::Vector3d& p) { xyz.block<1, 3>(f, 3 * m) = p.transpose(); }
  void clear(int f, int m) { xyz.block<1, 3>(f, 3 * m).setConstant(std::numeric_limits<double>::quiet_NaN()); }
};

// InputError naming `source` unless: a finite rate > 0, xyz of 3·labels columns, every sample
// either three finite numbers or three NaN, labels non-empty and free of tabs and line ends.
void check_marker_data(const MarkerData& d, const std::string& source);

// The factor from a file's length unit to millimetres ("mm", "cm", "m"; case-insensitive;
// empty = mm). InputError naming `source` for another unit.
double millimetres_per_unit(const std::string& unit, const std::string& source);

// Reads a .c3d or .trc file (by extension, case-insensitive); InputError for another.
MarkerData read_markers(const std::filesystem::path& path);

// Writes .c3d (floating-point, Intel) or .trc by extension, atomically.
void write_markers(const std::filesystem::path& path, const MarkerData& d);

// The fraction of samples that are missing (0 for an empty capture).
double missing_fraction(const MarkerData& d);

}  // namespace bodymodel
