#include "core/io/csv.h"

#include "core/error.h"
#include "core/io/atomic_write.h"

namespace bodymodel {

namespace {

constexpr std::string_view kBom = "\xEF\xBB\xBF";

// Reads one record from text[pos...]; leaves pos after its line end. `open_quote_line` gets the
// line a quoted field that is never closed started on (0 when every quote closed).
std::vector<std::string> read_record(std::string_view text, size_t& pos, int& line, int& open_quote_line) {
  std::vector<std::string> out;
  std::string cell;
  bool quoted = false;      // inside a quoted field
  bool was_quoted = false;  // the current cell had a quoted part (not trimmed then)
  open_quote_line = 0;
  auto finish_cell = [&] {
    if (!was_quoted)
      while (!cell.empty() && (cell.back() == ' ' || cell.back() == '\r')) cell.pop_back();
    out.push_back(std::move(cell));
    cell.clear();
    was_quoted = false;
  };
  while (pos < text.size()) {
    const char c = text[pos++];
    if (quoted) {
      if (c == '"') {
        if (pos < text.size() && text[pos] == '"') {
          cell += '"';
          ++pos;
        } else {
          quoted = false;
          open_quote_line = 0;
        }
      } else {
        if (c == '\n') ++line;
        cell += c;
      }
    } else if (c == '"' && !was_quoted && cell.find_first_not_of(' ') == std::string::npos) {
      cell.clear();  // spaces before an opening quote
      quoted = was_quoted = true;
      open_quote_line = line;
    } else if (c == ',') {
      finish_cell();
    } else if (c == '\n') {
      ++line;
      finish_cell();
      return out;
    } else if (c == '\r' && was_quoted) {
      // "a",  CRLF after a quoted field: not part of it
    } else if (was_quoted && c == ' ') {
      // spaces between a closing quote and the comma
    } else {
      cell += c;
    }
  }
  finish_cell();  // a quote left open: open_quote_line says where; the caller decides
  return out;
}

bool blank(const std::vector<std::string>& fields) { return fields.size() == 1 && fields[0].empty(); }

}  // namespace

std::string_view without_bom(std::string_view text) {
  return text.substr(0, kBom.size()) == kBom ? text.substr(kBom.size()) : text;
}

std::string csv_field(std::string_view s) {
  // A trailing space would be trimmed on reading, a leading byte-order mark dropped (in a file's
  // first cell): quoted, both stay.
  const bool quote = s.find_first_of(",\"\r\n") != std::string_view::npos || (!s.empty() && s.back() == ' ') ||
                     s.substr(0, kBom.size()) == kBom;
  if (!quote) return std::string(s);
  std::string q = "\"";
  for (char c : s) {
    if (c == '"') q += '"';
    q += c;
  }
  return q + "\"";
}

std::string csv_row(const std::vector<std::string>& fields) {
  std::string r;
  for (size_t i = 0; i < fields.size(); ++i) {
    if (i) r += ',';
    r += csv_field(fields[i]);
  }
  return r;
}

std::vector<CsvRecord> parse_csv(std::string_view text, const std::string& source) {
  text = without_bom(text);
  std::vector<CsvRecord> out;
  size_t pos = 0;
  int line = 1;
  while (pos < text.size()) {
    const int start = line;
    int open = 0;
    std::vector<std::string> fields = read_record(text, pos, line, open);
    if (open)
      throw InputError("'" + source + "' line " + std::to_string(open) +
                       ": a quoted field is not closed (a '\"' without its closing '\"')");
    if (blank(fields)) continue;
    out.push_back({std::move(fields), start});
  }
  return out;
}

std::vector<CsvRecord> read_csv_file(const std::filesystem::path& path) {
  return parse_csv(read_text_file(path), path.string());
}

std::vector<std::string> split_csv_line(const std::string& line) {
  const std::string_view text = without_bom(line);
  if (text.empty()) return {};
  size_t pos = 0;
  int n = 1, open = 0;
  std::vector<std::string> out = read_record(text, pos, n, open);
  // A quote left open runs to the end of the line: lenient, as a line has no more.
  // A line ending in "\n" (getline leaves none, but a caller may pass one) gives no extra cell.
  return out;
}

}  // namespace bodymodel
