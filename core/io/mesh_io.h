// Mesh and point-cloud files: OBJ, PLY (ASCII and binary little-endian) and OFF (ASCII,
// core/io/off.h).
//
// Readers are strict: a malformed file throws InputError naming the file, the line (or
// element) and what was wrong. Writers go through write_atomically, so a failed write never
// leaves a partial file under the final name.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "core/mesh.h"

namespace bodymodel {

// Everything an OBJ holds that we use: positions, polygons (any size, 0-based), and the group
// ('g') of each polygon ("" before the first g line).
struct ObjContents {
  Eigen::MatrixX3d V;                        // #V by 3
  std::vector<std::vector<int>> polygons;    // #P polygons, 0-based vertex indices
  std::vector<int> polygon_group;            // #P index into group_names
  std::vector<std::string> group_names;
};

ObjContents read_obj_contents(const std::filesystem::path& path);
// The same from memory; `source` names the input in error messages.
ObjContents parse_obj(std::string_view text, const std::string& source);

// Triangulates polygons as fans (a quad a b c d gives a b c and a c d).
Eigen::MatrixX3i triangulate(const std::vector<std::vector<int>>& polygons);

// Reads OBJ, PLY or OFF (by extension) as a triangle mesh; quads and polygons are triangulated
// (OFF: core/io/off.h).
Mesh read_mesh(const std::filesystem::path& path);
// Writes OBJ, PLY or OFF (by extension). PLY is binary little-endian unless `ascii`.
// colors: #V by 3 in [0,1] (PLY only; ignored for OBJ), or empty.
void write_mesh(const std::filesystem::path& path, const Eigen::MatrixX3d& V,
                const Eigen::MatrixX3i& F, const Eigen::MatrixX3d& colors = {},
                bool ascii = false);
inline void write_mesh(const std::filesystem::path& path, const Mesh& m) {
  write_mesh(path, m.V, m.F);
}

// PLY point cloud with optional normals (nx ny nz). Faces in the file are ignored.
PointCloud read_point_cloud(const std::filesystem::path& path);

// From memory (tests, fuzzing): `format` is "obj", "ply" or "off"; `source` names it in errors.
Mesh parse_mesh(const std::string& bytes, const std::string& format, const std::string& source);
PointCloud parse_ply_point_cloud(const std::string& bytes, const std::string& source);
void write_point_cloud(const std::filesystem::path& path, const PointCloud& cloud,
                       bool ascii = false);

}  // namespace bodymodel
