// The crowd viewer written beside a dressed crowd (`crowd --outfits`; docs/viewer.md#the-crowd-viewer):
// OUT/crowd.html (tools/viewer/crowd.html with the crowd's glb files as its default list) and the
// three.js modules it imports under OUT/three/ (three.module.js, GLTFLoader, SkeletonUtils,
// BufferGeometryUtils), copied from a three package folder.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace bodymodel {

// `page` = the page's text (the executable's copy of tools/viewer/crowd.html); `glbs` = the glb
// files relative to `out`; `three_package` = a three.js npm package folder (…/node_modules/three).
// Returns false, writing the page only, when the package lacks a module the page imports.
// `out` must exist; files are written atomically; InputError when `glbs` is empty.
bool write_crowd_viewer(const std::filesystem::path& out, const std::string& page, const std::vector<std::string>& glbs,
                        const std::filesystem::path& three_package);

}  // namespace bodymodel
