// Names read from input files that become file names: mesh names stored in an encoding .npz,
// scan ids in a database's scans.csv, paths recorded in a model's metadata. A name from a file
// is data, not a path: it must never take a write (or a read) outside the folder it is meant
// for, whatever it holds ('..', '/', an absolute path, NUL, control characters, bytes that are
// not UTF-8). Every verb that names files after data (person ids, mesh names, scan ids) goes
// through unique_file_names or check_file_name.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace bodymodel {

// Why `name` is not a plain file name (one path component that stays in its folder), or "" when
// it is one: not empty, not "." or "..", no '/', '\\', ':', NUL or other control character,
// valid UTF-8 (file names end up in JSON, HTML and terminals), at most 200 bytes, and not
// starting with '.' (hidden, or a temporary of core/io/atomic_write.h).
std::string file_name_problem(std::string_view name);

// Throws InputError "<where>: <what> '<name>' is not a plain file name (<problem>)" unless
// file_name_problem(name) is empty. For names that must match files (scan ids).
void check_file_name(std::string_view name, const std::string& where, const std::string& what = "name");

// A plain file name made from `name`: plain names are returned unchanged; in others every '/',
// '\\', ':', control character (NUL included) and byte that is not part of valid UTF-8 becomes
// '_', leading '.' and '_' are dropped ("../../tmp/x" → "tmp_x") and the result is cut to 200
// bytes; nothing left → `fallback`.
std::string sanitized_file_name(std::string_view name, const std::string& fallback);

// sanitized_file_name of each name (fallback: fallback_prefix + "_NNN"), made unique
// case-insensitively (for case-insensitive file systems). A plain name that is the first of its
// spelling keeps it; a repeated or sanitised one gets "_2", "_3", … skipping every name taken or
// kept by another item, so {"1", "1", "1_2"} → {"1", "1_3", "1_2"}: no two items share a file.
std::vector<std::string> unique_file_names(const std::vector<std::string>& names,
                                           const std::string& fallback_prefix);

// Whether `s` is valid UTF-8 (no overlong forms, surrogates or code points past U+10FFFF).
bool valid_utf8(std::string_view s);

// `s` with every byte that is not part of valid UTF-8 replaced by U+FFFD: for text that goes
// into JSON, HTML or a message (a name read from a file or the command line).
std::string utf8_or_replaced(std::string_view s);

// The last component of `path` (trailing separators and "." ignored): what a file may record
// about where its inputs came from without embedding the machine's folders
// ("/home/u/db/" → "db", "../reg" → "reg", "/" → "").
std::string path_label(const std::filesystem::path& path);

}  // namespace bodymodel
