// The one CSV dialect of the project, for every table it reads or writes (RFC 4180):
//   - write: fields joined by ','; a field holding ',', '"', CR or LF (or ending in a space, or
//     starting with a byte-order mark, which a read would drop) is written in double quotes with
//     each '"' doubled; rows end in "\n";
//   - read: quoted fields (which may hold commas, doubled quotes and line ends), LF or CRLF line
//     ends, a UTF-8 byte-order mark before the first field dropped (spreadsheets write one),
//     unquoted cells trimmed of trailing spaces and CR, a trailing comma an empty last cell.
// Ids, file names and free text in a table are data: nothing of them may break a row.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace bodymodel {

// `s` as one CSV field (quoted only when it must be).
std::string csv_field(std::string_view s);

// The fields as one CSV row, each through csv_field, without a line end.
std::string csv_row(const std::vector<std::string>& fields);

// One record of a CSV text and the line (1-based) it starts on.
struct CsvRecord {
  std::vector<std::string> fields;
  int line = 0;
};

// Every record of `text`; blank lines are skipped. A quoted field that is never closed throws
// InputError "'<source>' line N: a quoted field is not closed".
std::vector<CsvRecord> parse_csv(std::string_view text, const std::string& source);

// parse_csv of a file's bytes; InputError naming the file when it cannot be read.
std::vector<CsvRecord> read_csv_file(const std::filesystem::path& path);

// The cells of one line, as parse_csv reads them (a quote left open runs to the end of the
// line; a byte-order mark at the start is dropped, so the header line of a file read line by
// line loses it too). "" gives no cells.
std::vector<std::string> split_csv_line(const std::string& line);

// `text` without a leading UTF-8 byte-order mark.
std::string_view without_bom(std::string_view text);

}  // namespace bodymodel
