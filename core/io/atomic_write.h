// Atomic file output: write to a temporary name in the same folder, rename when complete.
// An exception (or a crash) during writing leaves no file under the final name.
#pragma once

#include <filesystem>
#include <functional>
#include <ostream>
#include <string>

namespace bodymodel {

// Calls write(stream) on a temporary file beside `path`, flushes, checks the stream and
// renames it to `path`. Throws InputError naming the file on any failure (the temporary is
// removed). Binary mode.
void write_atomically(const std::filesystem::path& path,
                      const std::function<void(std::ostream&)>& write);

// Convenience: a whole string.
void write_text_file(const std::filesystem::path& path, const std::string& text);

// Reads a whole file; InputError naming it if it cannot be read.
std::string read_text_file(const std::filesystem::path& path);

// Creates `dir` (and parents); InputError naming it when that fails or it is not writable.
void ensure_directory(const std::filesystem::path& dir);

}  // namespace bodymodel
