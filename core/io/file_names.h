// Names read from input files that become file names: mesh names stored in an encoding .npz,
// scan ids in a database's scans.csv, paths recorded in a model's metadata. A name from a file
// is data, not a path: it must never take a write (or a read) outside the folder it is meant
// for, whatever it holds ('..', '/', an absolute path, NUL, control characters).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace bodymodel {

// Why `name` is not a plain file name (one path component that stays in its folder), or "" when
// it is one: not empty, not "." or "..", no '/', '\\', NUL or other control character, at most
// 200 bytes, and not starting with '.' (hidden, or a temporary of core/io/atomic_write.h).
std::string file_name_problem(std::string_view name);

// Throws InputError "<where>: <what> '<name>' is not a plain file name (<problem>)" unless
// file_name_problem(name) is empty. For names that must match files (scan ids).
void check_file_name(std::string_view name, const std::string& where, const std::string& what = "name");

// A plain file name made from `name`: plain names are returned unchanged; in others every '/',
// '\\', ':' and control character (NUL included) becomes '_', leading '.' and '_' are dropped
// ("../../tmp/x" → "tmp_x") and the result is cut to 200 bytes; nothing left → `fallback`.
std::string sanitized_file_name(std::string_view name, const std::string& fallback);

// sanitized_file_name of each name (fallback: fallback_prefix + "_NNN"), made unique: a name
// met before (case-insensitively, for case-insensitive file systems) gets "_2", "_3", … .
std::vector<std::string> unique_file_names(const std::vector<std::string>& names,
                                           const std::string& fallback_prefix);

// The last component of `path` (trailing separators and "." ignored): what a file may record
// about where its inputs came from without embedding the machine's folders
// ("/home/u/db/" → "db", "../reg" → "reg", "/" → "").
std::string path_label(const std::filesystem::path& path);

}  // namespace bodymodel
