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

// Length of the valid UTF-8 sequence at s[i], 0 when the byte there does not start one.
size_t utf8_length(std::string_view s, size_t i) {
  const unsigned char c = static_cast<unsigned char>(s[i]);
  if (c < 0x80) return 1;
  size_t n;
  unsigned cp;
  if (c >= 0xc2 && c <= 0xdf) n = 2, cp = c & 0x1f;
  else if (c >= 0xe0 && c <= 0xef) n = 3, cp = c & 0x0f;
  else if (c >= 0xf0 && c <= 0xf4) n = 4, cp = c & 0x07;
  else return 0;
  if (i + n > s.size()) return 0;
  for (size_t k = 1; k < n; ++k) {
    const unsigned char d = static_cast<unsigned char>(s[i + k]);
    if ((d & 0xc0) != 0x80) return 0;
    cp = (cp << 6) | (d & 0x3f);
  }
  if ((n == 3 && cp < 0x800) || (n == 4 && cp < 0x10000) || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff)) return 0;
  return n;
}

// The name shown in a message: control characters and bytes that are not UTF-8 as \xNN, cut
// to 60 bytes.
std::string printable(std::string_view s) {
  std::string out;
  const std::string_view shown = s.substr(0, 60);
  for (size_t i = 0; i < shown.size();) {
    const unsigned char c = static_cast<unsigned char>(shown[i]);
    const size_t n = utf8_length(shown, i);
    if (n == 0 || c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
      ++i;
    } else {
      out.append(shown.substr(i, n));
      i += n;
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
  if (!valid_utf8(name)) return "it holds bytes that are not UTF-8";
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
  for (size_t i = 0; i < name.size();) {
    const size_t n = utf8_length(name, i);
    if (n == 0 || (n == 1 && bad_char(static_cast<unsigned char>(name[i])))) {
      out.push_back('_');
      ++i;
    } else {
      out.append(name.substr(i, n));
      i += n;
    }
  }
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
  auto lower = [](std::string s) {
    for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
  };
  std::vector<std::string> out(names.size());
  std::set<std::string> taken;  // lower case
  // First the plain names, each the first of its spelling: they keep their names, so a later
  // "_2" made for a repeated name can never take one of them.
  std::vector<char> kept(names.size(), 0);
  for (size_t i = 0; i < names.size(); ++i)
    if (file_name_problem(names[i]).empty() && taken.insert(lower(names[i])).second) {
      out[i] = names[i];
      kept[i] = 1;
    }
  // Then every other name: sanitised, and suffixed past every name taken.
  for (size_t i = 0; i < names.size(); ++i) {
    if (kept[i]) continue;
    char index[24];
    std::snprintf(index, sizeof index, "_%03zu", i);
    const std::string base = sanitized_file_name(names[i], fallback_prefix + index);
    std::string name = base;
    for (int k = 2; taken.count(lower(name)); ++k) {
      const std::string suffix = "_" + std::to_string(k);
      // Stay within the length limit (cut at a UTF-8 boundary).
      std::string stem = base.substr(0, std::min(base.size(), kMaxName - suffix.size()));
      auto continuation = [&](size_t at) { return (static_cast<unsigned char>(base[at]) & 0xc0) == 0x80; };
      while (stem.size() < base.size() && !stem.empty() && continuation(stem.size())) stem.pop_back();
      name = stem + suffix;
    }
    taken.insert(lower(name));
    out[i] = name;
  }
  return out;
}

bool valid_utf8(std::string_view s) {
  for (size_t i = 0; i < s.size();) {
    const size_t n = utf8_length(s, i);
    if (n == 0) return false;
    i += n;
  }
  return true;
}

std::string utf8_or_replaced(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (size_t i = 0; i < s.size();) {
    const size_t n = utf8_length(s, i);
    if (n == 0) {
      out += "\xEF\xBF\xBD";  // U+FFFD
      ++i;
    } else {
      out.append(s.substr(i, n));
      i += n;
    }
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
