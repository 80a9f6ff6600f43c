#include "markers/trc.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <map>
#include <vector>

#include "core/error.h"
#include "core/io/atomic_write.h"

namespace bodymodel {
namespace {

struct Lines {
  std::vector<std::string> lines;
  const std::string& source;
  [[noreturn]] void fail(size_t line, const std::string& what) const {
    throw InputError("TRC '" + source + "' line " + std::to_string(line + 1) + ": " + what);
  }
};

std::vector<std::string> split_tabs(const std::string& line) {
  std::vector<std::string> out(1);
  for (char c : line) {
    if (c == '\t') out.emplace_back();
    else out.back() += c;
  }
  return out;
}

std::string trimmed(const std::string& s) {
  size_t a = 0, b = s.size();
  while (a < b && (s[a] == ' ' || s[a] == '\r')) ++a;
  while (b > a && (s[b - 1] == ' ' || s[b - 1] == '\r')) --b;
  return s.substr(a, b - a);
}

// A whole cell as a finite number; false when it is not one.
bool number(const std::string& cell, double& v) {
  const std::string t = trimmed(cell);
  if (t.empty()) return false;
  const char* end = t.data() + t.size();
  if (t[0] == '+') return number(t.substr(1), v);
  auto r = std::from_chars(t.data(), end, v);
  return r.ec == std::errc() && r.ptr == end && std::isfinite(v);
}

// The header's keys (line 2) with their values (line 3).
std::map<std::string, std::string> header_values(const Lines& in) {
  const auto keys = split_tabs(in.lines[1]), values = split_tabs(in.lines[2]);
  std::map<std::string, std::string> h;
  for (size_t k = 0; k < keys.size(); ++k)
    if (!trimmed(keys[k]).empty()) h[trimmed(keys[k])] = k < values.size() ? trimmed(values[k]) : "";
  return h;
}

double header_number(const Lines& in, const std::map<std::string, std::string>& h, const char* key) {
  auto it = h.find(key);
  double v = 0;
  if (it == h.end()) in.fail(1, std::string("no ") + key + " in the header");
  if (!number(it->second, v)) in.fail(2, std::string(key) + " '" + it->second + "' is not a number");
  return v;
}

void read_rows(const Lines& in, size_t first_row, MarkerData& d) {
  const int M = d.marker_count();
  std::vector<size_t> rows;
  for (size_t i = first_row; i < in.lines.size(); ++i)
    if (!trimmed(in.lines[i]).empty()) rows.push_back(i);
  d.xyz.setConstant(static_cast<Eigen::Index>(rows.size()), 3 * M, std::numeric_limits<double>::quiet_NaN());
  for (size_t f = 0; f < rows.size(); ++f) {
    const auto cells = split_tabs(in.lines[rows[f]]);
    double frame = 0;
    if (!number(cells[0], frame) || frame != std::floor(frame) || std::abs(frame) > 1e9)
      in.fail(rows[f], "column 1: frame number '" + trimmed(cells[0]) + "' is not an integer");
    if (f == 0) d.first_frame = static_cast<int>(frame);
    for (size_t c = 2 + 3 * size_t(M); c < cells.size(); ++c)
      if (!trimmed(cells[c]).empty()) in.fail(rows[f], "column " + std::to_string(c + 1) + ": more cells than 3 per marker");
    for (int m = 0; m < M; ++m) {
      double v[3];
      int found = 0;
      for (int k = 0; k < 3; ++k) {
        const size_t c = 2 + 3 * size_t(m) + k;
        const std::string cell = c < cells.size() ? trimmed(cells[c]) : "";
        if (cell.empty()) continue;
        if (!number(cell, v[k])) in.fail(rows[f], "column " + std::to_string(c + 1) + ": '" + cell + "' is not a finite number");
        ++found;
      }
      if (found == 3) d.set(static_cast<int>(f), m, Eigen::Vector3d(v[0], v[1], v[2]));
      else if (found != 0) in.fail(rows[f], "marker '" + d.labels[m] + "' has " + std::to_string(found) + " of its 3 coordinates");
    }
  }
}

}  // namespace

MarkerData parse_trc(const std::string& text, const std::string& source) {
  Lines in{{}, source};
  std::string cur;
  for (char c : text) {
    if (c == '\n') in.lines.push_back(trimmed(cur)), cur.clear();
    else cur += c;
  }
  if (!cur.empty()) in.lines.push_back(trimmed(cur));
  if (in.lines.size() < 5) throw InputError("TRC '" + source + "': truncated (fewer than the 5 header lines)");
  if (in.lines[0].rfind("PathFileType", 0) != 0) in.fail(0, "not a TRC file (does not start with PathFileType)");
  const auto h = header_values(in);
  MarkerData d;
  d.rate = h.count("DataRate") ? header_number(in, h, "DataRate") : header_number(in, h, "CameraRate");
  if (d.rate <= 0) in.fail(2, "DataRate must be positive");
  const double declared_markers = header_number(in, h, "NumMarkers");
  const double declared_frames = header_number(in, h, "NumFrames");
  const double mm = millimetres_per_unit(h.count("Units") ? h.at("Units") : "", "TRC '" + source + "' Units");
  const auto names = split_tabs(in.lines[3]);
  for (size_t c = 2; c < names.size(); ++c)
    if (!trimmed(names[c]).empty()) {
      if ((c - 2) % 3 != 0) in.fail(3, "column " + std::to_string(c + 1) + ": a marker name not on a multiple of 3 columns");
      d.labels.push_back(trimmed(names[c]));
    }
  if (declared_markers != double(d.labels.size()))
    in.fail(2, "NumMarkers is " + h.at("NumMarkers") + " but line 4 names " + std::to_string(d.labels.size()) + " markers");
  // Never allocate from a count the file does not back: a missing sample still costs a tab.
  if (declared_frames < 0 || declared_frames * double(d.labels.size()) > std::max(1e6, 4.0 * double(text.size())))
    in.fail(2, "NumFrames " + h.at("NumFrames") + " × NumMarkers " + h.at("NumMarkers") + " is absurd for a file of " +
                   std::to_string(text.size()) + " bytes");
  read_rows(in, 5, d);
  if (double(d.frame_count()) != declared_frames)
    in.fail(2, "NumFrames is " + h.at("NumFrames") + " but the file holds " + std::to_string(d.frame_count()) + " rows");
  d.xyz *= mm;
  check_marker_data(d, "TRC '" + source + "'");
  return d;
}

MarkerData read_trc(const std::filesystem::path& path) { return parse_trc(read_text_file(path), path.string()); }

namespace {
std::string shortest(double v) {
  char buf[64];
  auto r = std::to_chars(buf, buf + sizeof buf, v);  // the shortest text that reads back exactly
  return std::string(buf, r.ptr);
}
}  // namespace

std::string trc_text(const MarkerData& d, const std::string& file_name) {
  check_marker_data(d, "TRC output");
  const int M = d.marker_count(), F = d.frame_count();
  std::string s = "PathFileType\t4\t(X/Y/Z)\t" + file_name + "\n";
  s += "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n";
  const std::string rate = shortest(d.rate);
  s += rate + "\t" + rate + "\t" + std::to_string(F) + "\t" + std::to_string(M) + "\tmm\t" + rate + "\t" +
       std::to_string(d.first_frame) + "\t" + std::to_string(F) + "\n";
  s += "Frame#\tTime";
  for (const auto& l : d.labels) s += "\t" + l + "\t\t";
  s += "\n\t";
  for (int m = 1; m <= M; ++m) s += "\tX" + std::to_string(m) + "\tY" + std::to_string(m) + "\tZ" + std::to_string(m);
  s += "\n\n";
  char t[64];
  for (int f = 0; f < F; ++f) {
    std::snprintf(t, sizeof t, "%.6f", f / d.rate);
    s += std::to_string(d.first_frame + f) + "\t" + t;
    for (int m = 0; m < M; ++m) {
      if (!d.present(f, m)) {
        s += "\t\t\t";
        continue;
      }
      for (int k = 0; k < 3; ++k) s += "\t" + shortest(d.xyz(f, 3 * m + k));
    }
    s += "\n";
  }
  return s;
}

void write_trc(const std::filesystem::path& path, const MarkerData& d) {
  write_text_file(path, trc_text(d, path.filename().string()));
}

}  // namespace bodymodel
