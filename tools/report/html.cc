#include "tools/report/html.h"

#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/io/csv.h"

namespace bodymodel {

namespace fs = std::filesystem;

std::string html_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

std::string html_table_from_csv(const fs::path& csv, const std::string& href, int max_rows) {
  std::error_code ec;
  std::vector<CsvRecord> rows;
  try {
    if (fs::is_regular_file(csv, ec)) rows = read_csv_file(csv);  // quoted cells shown as their text
  } catch (const InputError&) {
    rows.clear();
  }
  if (rows.empty()) return "<p class=\"missing\">missing table: " + html_escape(href) + "</p>\n";
  std::string out = "<table>\n";
  int row = 0, dropped = 0;
  for (const auto& r : rows) {
    if (row > max_rows) {
      ++dropped;
      continue;
    }
    out += "<tr>";
    for (const auto& cell : r.fields)
      out += (row == 0 ? "<th>" : "<td>") + html_escape(cell) + (row == 0 ? "</th>" : "</td>");
    out += "</tr>\n";
    ++row;
  }
  out += "</table>\n<p class=\"src\"><a href=\"" + html_escape(href) + "\">" + html_escape(href) + "</a>";
  if (dropped) out += " (" + std::to_string(dropped) + " more rows in the file)";
  return out + "</p>\n";
}

std::string html_figure(const fs::path& file, const std::string& href, const std::string& caption) {
  std::error_code ec;
  if (!fs::exists(file, ec)) return "<p class=\"missing\">missing picture: " + html_escape(href) + "</p>\n";
  return "<figure><a href=\"" + html_escape(href) + "\"><img src=\"" + html_escape(href) + "\" alt=\"" +
         html_escape(caption) + "\"></a><figcaption>" + caption + "</figcaption></figure>\n";
}

std::string html_page(const std::string& title, const std::string& body) {
  return "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>" + html_escape(title) +
         "</title>\n<style>\nbody{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}\n"
         "table{border-collapse:collapse;margin:.5em 0;font-size:90%}td,th{border:1px solid #bbb;padding:2px 8px;"
         "text-align:right}th{background:#eee}\nfigure{display:inline-block;margin:.5em;vertical-align:top}"
         "img{max-width:100%;border:1px solid #ddd}\nfigcaption{font-size:90%;max-width:600px}"
         ".pair{display:flex;gap:1em}.pair figure{flex:1;margin:.5em 0}\n"
         ".missing{color:#b00;font-weight:bold}.src{font-size:85%}\n</style></head><body>\n<h1>" +
         html_escape(title) + "</h1>\n" + body + "</body></html>\n";
}

}  // namespace bodymodel
