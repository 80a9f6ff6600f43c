#include "tools/pipeline/crowd_viewer.h"

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/io/atomic_write.h"

namespace bodymodel {

namespace fs = std::filesystem;

bool write_crowd_viewer(const fs::path& out, const std::string& page, const std::vector<std::string>& glbs,
                        const fs::path& three_package) {
  if (glbs.empty()) throw InputError("crowd viewer: no glb files to show");
  // The page reads window.CROWD_FILES when its URL gives no files=.
  const std::string files = "<script>window.CROWD_FILES = " + nlohmann::json(glbs).dump() + ";</script>\n";
  const std::string marker = "<script type=\"importmap\">";
  const size_t at = page.find(marker);
  if (at == std::string::npos) throw InputError("crowd viewer: the page has no import map");
  write_text_file(out / "crowd.html", page.substr(0, at) + files + page.substr(at));
  const char* modules[] = {"build/three.module.js", "examples/jsm/loaders/GLTFLoader.js",
                           "examples/jsm/utils/SkeletonUtils.js", "examples/jsm/utils/BufferGeometryUtils.js"};
  for (const char* m : modules)
    if (!fs::is_regular_file(three_package / m)) return false;
  for (const char* m : modules) {
    const fs::path to = out / "three" / m;
    fs::create_directories(to.parent_path());
    write_text_file(to, read_text_file(three_package / m));
  }
  return true;
}

}  // namespace bodymodel
