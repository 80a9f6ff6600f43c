// A static HTML report (opens from disk, relative links only): sections of pictures and tables,
// tables read from the CSV files written beside them (and linked).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace bodymodel {

// Escapes &, <, >, " for HTML text.
std::string html_escape(const std::string& s);

// A CSV file as an HTML table with a link to the file (`href` relative to the report);
// at most `max_rows` data rows (the rest is counted). A missing file gives a visible note.
std::string html_table_from_csv(const std::filesystem::path& csv, const std::string& href, int max_rows = 40);

// An image with a caption; a missing file gives a visible note instead.
std::string html_figure(const std::filesystem::path& file, const std::string& href, const std::string& caption);

// A whole page around `body` (title, a little CSS).
std::string html_page(const std::string& title, const std::string& body);

}  // namespace bodymodel
