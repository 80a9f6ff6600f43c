// Writing .npz archives with deflated members (numpy's savez_compressed layout; np.load and
// Npz::load read them like stored ones). Npz::save/serialize write stored members.
#pragma once

#include <filesystem>
#include <string>

#include "core/io/npz.h"

namespace bodymodel {

struct NpzWriteOptions {
  bool compress = false;  // deflate every member (a member deflate cannot shrink stays stored)
  int level = 6;          // zlib level 1 (fastest) .. 9 (smallest)
};

// Throws InputError for a level outside 1..9 (when compressing) or a member over 4 GiB.
std::string serialize_npz(const Npz& npz, const NpzWriteOptions& options);
// Atomic write (core/io/atomic_write.h).
void save_npz(const std::filesystem::path& path, const Npz& npz, const NpzWriteOptions& options);

}  // namespace bodymodel
