// OFF (Object File Format, ASCII): the format of the FAUST and SCAPE meshes. read_mesh,
// write_mesh and read_point_cloud (core/io/mesh_io.h) read and write it by the extension .off;
// this header adds the parser for data in memory (tests, fuzzing).
//
// Accepted: an optional header line "OFF" (also COFF/NOFF/CNOFF/STOFF, whose extra per-vertex
// values are skipped; the counts may follow on the same line), the counts line
// "#V #F [#E]", #V lines "x y z [...]" and #F lines "k i_1 … i_k [colour]" with 0-based
// indices; '#' starts a comment. Strict: the counts must match the lines that follow (too few or
// too many is an InputError naming the line), a face needs k ≥ 3 vertices with indices in
// 0..#V−1, coordinates must be finite, counts the file cannot hold are refused before anything is
// allocated, and binary OFF is refused by name. Polygons are kept as they are; read_mesh
// triangulates k > 3 as fans, as it does for OBJ and PLY. write_mesh writes "OFF", the counts
// with 0 edges, coordinates with 9 significant digits and triangles.
#pragma once

#include <string>
#include <string_view>

#include "core/io/mesh_io.h"

namespace bodymodel {

// Positions and polygons of an OFF file in memory; `source` names it in errors. (ObjContents's
// groups: one unnamed group.)
ObjContents parse_off(std::string_view text, const std::string& source);

}  // namespace bodymodel
