// libigl's small text/binary formats used by skinning data sets (see
// $BODYMODEL_DATA/animations/README.md, "File formats"; docs/data.md):
//   .tgf   skeleton graph: joint positions and parent→child edges (every edge is a bone)
//   .dmat  dense matrix, ASCII ("ncols nrows" then column-major values) or binary
//          ("0 0\n", "ncols nrows\n", then little-endian float64, column-major)
//   .Tmat  one pose's stacked bone transforms: 4·#B rows of 3 numbers, block j = [R_jᵀ; t_jᵀ]
// Readers are strict: a malformed file throws InputError naming the file, the line and what was
// expected and found. Writers go through write_atomically.
#pragma once

#include <Eigen/Core>
#include <filesystem>

#include "core/skeleton.h"

namespace bodymodel {

struct TgfGraph {
  Eigen::MatrixX3d C;   // #J by 3 joint positions (file order)
  Eigen::MatrixX2i E;   // #E by 2 edges (bones) as 0-based joint indices, parent → child
};

// Reads a .tgf file. Extra columns on joint and edge lines are ignored (as libigl does).
TgfGraph read_tgf(const std::filesystem::path& path);

// Reads a .dmat file (ASCII or binary, detected from the header). Returns #rows by #cols.
Eigen::MatrixXd read_dmat(const std::filesystem::path& path);

// Writes a .dmat file; binary (float64, as libigl writes with ascii=false) unless `ascii`.
void write_dmat(const std::filesystem::path& path, const Eigen::MatrixXd& M, bool ascii = false);

// Converts a stacked transform matrix T (4·#B by 3, block j = [R_jᵀ; t_jᵀ], libigl convention
// U = [V 1]·T) into per-bone affine maps. `what` names the source in errors.
BoneTransforms bone_transforms_from_stacked(const Eigen::MatrixXd& T, const std::string& what);

// The inverse of bone_transforms_from_stacked: 4·#B by 3.
Eigen::MatrixXd stacked_from_bone_transforms(const BoneTransforms& M);

// Reads a .Tmat file (one pose: 4·#B lines of 3 numbers).
BoneTransforms read_tmat(const std::filesystem::path& path);

// Reads libigl's animation layout (the 408 tutorial's elephant-anim.dmat): a DMAT with 12·#B rows
// and one column per frame; column f, read column-major as 4·#B by 3, is frame f's stack.
std::vector<BoneTransforms> read_transform_animation(const std::filesystem::path& path);

}  // namespace bodymodel
