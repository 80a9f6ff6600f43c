// TRC marker files (the tab-separated text of OpenSim and most exporters):
//   PathFileType  4  (X/Y/Z)  name.trc
//   DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
//   100  100  1000  350  mm  100  1  1000
//   Frame#  Time  M1 (two empty cells)  M2 …
//           X1  Y1  Z1  X2 …
//   (an optional blank line, then one row per frame: frame number, time, 3 numbers per marker)
// Empty fields (or a row that ends early) are missing samples. Units mm, cm or m (read as mm).
#pragma once

#include <filesystem>
#include <string>

#include "markers/marker_data.h"

namespace bodymodel {

// Parses TRC text; `source` names the file in errors (with the line and column).
MarkerData parse_trc(const std::string& text, const std::string& source);
MarkerData read_trc(const std::filesystem::path& path);

// The capture as TRC text (mm, 6 decimals: exact to well below the 1 µm of any capture).
std::string trc_text(const MarkerData& d, const std::string& file_name = "markers.trc");
void write_trc(const std::filesystem::path& path, const MarkerData& d);

}  // namespace bodymodel
