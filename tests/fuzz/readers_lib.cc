// The fuzz targets' readers, compiled once for all targets (see fuzz_common.h).
#include "fuzz_common.h"
#include "readers.h"

namespace bodymodel::fuzz {
const std::function<void(const std::string&)>& reader(const std::string& target) {
  return readers().at(target);
}
}  // namespace bodymodel::fuzz
