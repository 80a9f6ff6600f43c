// Plain-array mesh and point-cloud types shared by every stage.
//
// The core takes arrays, the edges do files: algorithms take these structs (or their Eigen
// members directly); readers and writers live in core/io/.
#pragma once

#include <Eigen/Core>

namespace bodymodel {

using RowMatrixX3d = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

// A triangle mesh.
//   V  #V by 3  vertex positions (millimetres for bodies; a data set's own unit otherwise)
//   F  #F by 3  vertex indices per triangle, 0-based, counter-clockwise seen from outside
struct Mesh {
  Eigen::MatrixX3d V;
  Eigen::MatrixX3i F;
};

// A point cloud, e.g. a scan.
//   P  #P by 3  positions
//   N  #P by 3  unit normals, or 0 rows when the cloud has none
struct PointCloud {
  Eigen::MatrixX3d P;
  Eigen::MatrixX3d N;
  bool has_normals() const { return N.rows() == P.rows() && P.rows() > 0; }
};

}  // namespace bodymodel
