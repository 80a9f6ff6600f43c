#include "core/io/atomic_write.h"

#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "core/error.h"

namespace bodymodel {

namespace fs = std::filesystem;

void write_atomically(const fs::path& path, const std::function<void(std::ostream&)>& write) {
  static std::atomic<int> counter{0};
  std::error_code ec;
  // "out/" or an existing folder: a file name is expected (rename would say "Not a directory").
  if (path.filename().empty() || fs::is_directory(path, ec))
    throw InputError("cannot write '" + path.string() + "': it is a folder; expected a file name");
  fs::path dir = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  if (!fs::is_directory(dir, ec))
    throw InputError("cannot write '" + path.string() + "': folder '" + dir.string() +
                     "' does not exist");
  fs::path tmp = dir / ("." + path.filename().string() + ".tmp" + std::to_string(getpid()) + "_" +
                        std::to_string(counter++));
  try {
    {
      errno = 0;
      std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
      // errno says why (read-only file system, permission denied, no space, ...).
      if (!out)
        throw InputError("cannot write '" + path.string() + "': " +
                         (errno ? std::string(std::strerror(errno)) : std::string("folder not writable")));
      write(out);
      errno = 0;
      out.flush();
      if (!out)
        throw InputError("cannot write '" + path.string() + "': write failed (" +
                         (errno ? std::string(std::strerror(errno)) : std::string("disk full?")) + ")");
    }
    fs::rename(tmp, path, ec);
    if (ec) throw InputError("cannot write '" + path.string() + "': " + ec.message());
  } catch (...) {
    fs::remove(tmp, ec);
    throw;
  }
}

void write_text_file(const fs::path& path, const std::string& text) {
  write_atomically(path, [&](std::ostream& out) { out.write(text.data(), text.size()); });
}

std::string read_text_file(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec))
    throw InputError("cannot read '" + path.string() + "': it is a folder, not a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError("cannot read '" + path.string() + "': no such file or not readable");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw InputError("cannot read '" + path.string() + "': read error");
  return ss.str();
}

void ensure_directory(const fs::path& dir) {
  std::error_code made, ec;
  fs::create_directories(dir, made);
  // The reason is create_directories' (read-only file system, permission denied, a file in the
  // way), not that of the check after it ("No such file or directory").
  if (!fs::is_directory(dir, ec)) {
    std::string why = made ? made.message() : std::string();
    if (fs::exists(dir, ec)) why = "a file of that name is in the way";
    throw InputError("cannot create folder '" + dir.string() + "'" + (why.empty() ? std::string() : ": " + why));
  }
  if (access(dir.c_str(), W_OK) != 0)
    throw InputError("folder '" + dir.string() + "' is not writable: " + std::strerror(errno));
}

}  // namespace bodymodel
