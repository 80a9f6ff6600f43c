#include "tools/pipeline/folder_settings.h"

#include <fmt/format.h>
#include <zlib.h>

#include <algorithm>
#include <fstream>
#include <vector>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/json_text.h"

namespace bodymodel {

namespace fs = std::filesystem;

std::string settings_difference(const fs::path& file, const nlohmann::json& settings) {
  // As written (json_text): a name with bytes that are not UTF-8 compares equal to its record.
  const nlohmann::json expected = nlohmann::json::parse(json_text(settings));
  const std::string name = file.filename().string();
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return "no " + name;
  nlohmann::json old;
  try {
    old = nlohmann::json::parse(read_text_file(file));
  } catch (const std::exception&) {
    return name + " does not parse";
  }
  if (!old.is_object()) return name + " is not a JSON object";
  if (old == expected) return "";
  auto shown = [](const nlohmann::json& v) {
    std::string s = json_text(v);
    return s.size() > 80 ? s.substr(0, 77) + "..." : s;
  };
  for (const auto& [key, value] : expected.items()) {
    if (!old.contains(key)) return key + " not recorded";
    if (old[key] != value) return fmt::format("{} was {}, now {}", key, shown(old[key]), shown(value));
  }
  for (const auto& [key, value] : old.items())
    if (!expected.contains(key)) return key + " recorded, not a setting now";
  return name + " differs";
}

std::string file_fingerprint(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::error_code ec;
  if (!in || fs::is_directory(path, ec))
    throw InputError("cannot read '" + path.string() + "': no such file or not readable");
  uLong crc = crc32(0L, Z_NULL, 0);
  std::vector<char> buf(1 << 20);
  uint64_t bytes = 0;
  while (in) {
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    const std::streamsize n = in.gcount();
    if (n <= 0) break;
    crc = crc32(crc, reinterpret_cast<const Bytef*>(buf.data()), static_cast<uInt>(n));
    bytes += static_cast<uint64_t>(n);
  }
  if (in.bad()) throw InputError("cannot read '" + path.string() + "': read error");
  return fmt::format("crc32 {:08x}, {} bytes", static_cast<uint32_t>(crc), bytes);
}

ResumableFolder::ResumableFolder(fs::path dir, std::string record, nlohmann::json settings, bool force,
                                 std::function<bool(const std::string&)> is_output)
    : dir_(std::move(dir)), record_(std::move(record)), settings_(std::move(settings)), is_output_(std::move(is_output)) {
  std::error_code ec;
  if (fs::exists(dir_, ec) && !fs::is_directory(dir_, ec))
    throw InputError("output '" + dir_.string() + "' exists and is not a folder");
  if (!fs::is_directory(dir_, ec)) return;  // a new folder
  for (auto it = fs::directory_iterator(dir_, ec); !ec && it != fs::directory_iterator(); it.increment(ec))
    if (is_output_(it->path().filename().string())) {
      had_outputs_ = true;
      break;
    }
  const fs::path record_path = dir_ / record_;
  const bool has_record = fs::exists(record_path, ec);
  if (!has_record && !had_outputs_) return;  // nothing of ours: a fresh start
  difference_ = settings_difference(record_path, settings_);
  if (difference_.empty()) {
    resume_ = true;
    return;
  }
  if (force) return;
  if (!has_record)
    throw InputError(fmt::format("output folder '{}' holds earlier outputs but no {} (made by an older bodymodel or "
                                 "another command), so their settings are unknown; use another folder, or --force to "
                                 "replace them",
                                 dir_.string(), record_));
  throw InputError(fmt::format("output folder '{}' holds outputs made with other settings ({}); use another folder, "
                               "or --force to replace them",
                               dir_.string(), difference_));
}

bool ResumableFolder::open(bool allow_resume) {
  ensure_directory(dir_);
  const bool resume = resume_ && allow_resume;
  if (!resume) {
    // The record goes first, so an interrupted clean-up leaves outputs without a record (refused
    // on the rerun), never old outputs under the new record.
    std::error_code ec;
    fs::remove(dir_ / record_, ec);
    std::vector<fs::path> old;
    for (auto it = fs::directory_iterator(dir_, ec); !ec && it != fs::directory_iterator(); it.increment(ec))
      if (is_output_(it->path().filename().string())) old.push_back(it->path());
    for (const auto& p : old) {
      fs::remove_all(p, ec);
      if (ec) throw InputError("cannot remove the earlier output '" + p.string() + "': " + ec.message());
    }
    write_text_file(dir_ / record_, json_text(settings_, 2) + "\n");
  }
  return resume;
}

std::function<bool(const std::string&)> outputs_named(std::vector<std::string> names, std::vector<std::string> suffixes) {
  return [names = std::move(names), suffixes = std::move(suffixes)](const std::string& n) {
    if (std::find(names.begin(), names.end(), n) != names.end()) return true;
    for (const auto& s : suffixes)
      if (n.size() > s.size() && n.compare(n.size() - s.size(), s.size(), s) == 0) return true;
    return false;
  };
}

}  // namespace bodymodel
