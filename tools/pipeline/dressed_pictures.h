// Pictures of a dressed crowd (`crowd --outfits`, for the demo's report), rendered headless by
// tools/render from the characters' dressed.glb files as exported: a line-up of the crowd, the
// levels of detail of one character side by side, and a close-up of its head (eyes, brows, hair).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "tools/render/render.h"

namespace bodymodel {

// The meshes of a dressed glb in file order (`write_dressed_character`: LOD0, LOD1, LOD2), each
// with its primitives concatenated at the bind (rest) pose, in the file's units (metres), every
// vertex coloured by its material's base colour converted from linear to sRGB (the picture shows
// the colour outfit.json lists). Node transforms are not applied: the dressed glb puts none on its
// mesh nodes. InputError naming the file when it cannot be read or has no triangle mesh.
std::vector<ColouredMesh> read_glb_meshes(const std::filesystem::path& glb);

struct DressedCrowdPictures {
  Image lineup;            // every character's LOD0 at rest, at most 10 a row, one scale
  Image lods;              // the featured character's levels side by side, flat-shaded (triangles show)
  Image closeup;           // its head from the front and from 40° to one side
  int featured = -1;       // the character of the two last pictures
  std::vector<int> level_triangles;  // of the featured character, per level
};

// Pictures of the characters crowd_dir/char_NNN/anim/dressed.glb, N < count (those present).
// The featured character is the first whose outfit.json has a "hair" item (else the first).
// InputError when there is no dressed.glb.
DressedCrowdPictures dressed_crowd_pictures(const std::filesystem::path& crowd_dir, int count);

// The pictures as DIR/crowd_dressed.png, crowd_lods.png and crowd_closeup.png (atomic writes).
void save_dressed_crowd_pictures(const DressedCrowdPictures& pictures, const std::filesystem::path& dir);

// The report's part on a dressed crowd (the demo's report: the crowd in OUT/crowd, the pictures
// saved in OUT/pictures, links relative to OUT): the three figures, OUT/crowd/outfits.csv as a
// table, and a link to the crowd viewer OUT/crowd/crowd.html, with the note that it must be served
// over http, when the page and the three.js modules it imports (OUT/crowd/three/) are there.
std::string dressed_crowd_html(const std::filesystem::path& out, const DressedCrowdPictures& pictures);

}  // namespace bodymodel
