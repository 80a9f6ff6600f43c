#include "core/io/file_names.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <set>

#include "core/error.h"

namespace bodymodel {

namespace {

constexpr size_t kMaxName = 200;  // bytes; file systems allow 255, leaving room for extensions

bool bad_char(unsigned char c) { return c < 0x20 || c == 0x7f || c == '/' || c == '\\' || c == ':'; }

// The name shown in a message: control characters as \xNN, cut to 60 bytes.
std::string printable(std::string_view s) {
  std::string out;
  for (unsigned char c : s.substr(0, 60)) {
    if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    } else {
      out.push_back(static_cast<char>(c));
    }
  }
  if (s.size() > 60) out += "…";
  return out;
}

}  // namespace

std::string file_name_problem(std::string_view name) {
  if (name.empty()) return "it is empty";
  if (name == "." || name == "..") return "it names a folder";
  if (name.size() > kMaxName)
    return "it is " + std::to_string(name.size()) + " bytes long, more than " + std::to_string(kMaxName);
  for (unsigned char c : name) {
    if (c == '/' || c == '\\') return "it holds a path separator";
    if (c == 0) return "it holds a NUL character";
    if (c < 0x20 || c == 0x7f) return "it holds a control character";
    if (c == ':') return "it holds ':'";
  }
  if (name[0] == '.') return "it starts with '.'";
  return "";
}

void check_file_name(std::string_view name, const std::string& where, const std::string& what) {
  const std::string problem = file_name_problem(name);
  if (!problem.empty())
    throw InputError(where + ": " + what + " '" + printable(name) + "' is not a plain file name (" + problem + ")");
}

std::string sanitized_file_name(std::string_view name, const std::string& fallback) {
  if (file_name_problem(name).empty()) return std::string(name);
  std::string out;
  out.reserve(name.size());
  for (unsigned char c : name) out.push_back(bad_char(c) ? '_' : static_cast<char>(c));
  // "../../tmp/x" → "tmp_x", "/abs" → "abs", ".hidden" → "hidden".
  out.erase(0, out.find_first_not_of("._"));
  if (out.size() > kMaxName) {
    out.resize(kMaxName);
    // Do not leave half of a UTF-8 sequence at the end.
    while (!out.empty() && (static_cast<unsigned char>(out.back()) & 0xc0) == 0x80) out.pop_back();
    if (!out.empty() && static_cast<unsigned char>(out.back()) >= 0xc0) out.pop_back();
  }
  return out.empty() ? fallback : out;
}

std::vector<std::string> unique_file_names(const std::vector<std::string>& names, const std::string& fallback_prefix) {
  std::vector<std::string> out;
  std::set<std::string> taken;  // lower case
  auto lower = [](std::string s) {
    for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
  };
  for (size_t i = 0; i < names.size(); ++i) {
    char index[24];
    std::snprintf(index, sizeof index, "_%03zu", i);
    const std::string base = sanitized_file_name(names[i], fallback_prefix + index);
    std::string name = base;
    for (int k = 2; taken.count(lower(name)); ++k) name = base + "_" + std::to_string(k);
    taken.insert(lower(name));
    out.push_back(name);
  }
  return out;
}

std::string path_label(const std::filesystem::path& path) {
  const std::filesystem::path p = path.lexically_normal();
  for (auto it = p.end(); it != p.begin();) {
    --it;
    const std::string s = it->string();
    if (!s.empty() && s != "." && s != "/" && s != "..") return s;
  }
  return "";
}

}  // namespace bodymodel
