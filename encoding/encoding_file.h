// Encoding files (`bodymodel encode` writes them, `decode` reads them): a NumPy .npz with
//   encodings          N by 15·#F float64, one row per input mesh, relative to `mean`
//                      (layout: encoding/relative_rotation_encoding.h)
//   mean               15·#F float64, the inputs' component-wise mean (absolute values)
//   template_vertices  #V by 3 float64, the template's rest vertices (input units, e.g. mm)
//   template_faces     #F by 3 int32, the template's triangles (0-based)
//   names              text: the input file stems, one per line (decoded meshes are named so)
//   layout             text: a one-paragraph description of the layout
// The names are data: decode writes files named after them only through unique_file_names
// (core/io/file_names.h), so a name holding '..', '/', an absolute path or NUL stays inside the
// output folder, and two rows of one name do not overwrite each other.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/io/npz.h"

namespace bodymodel {

struct EncodingFile {
  Eigen::MatrixXd encodings;            // N by 15·#F
  Eigen::VectorXd mean;                 // 15·#F
  Eigen::MatrixX3d template_vertices;   // #V by 3 (0 rows when the file has none)
  Eigen::MatrixX3i template_faces;      // #F by 3 (0 rows when the file has none)
  std::vector<std::string> names;       // N, as stored ("decoded_NNN" for rows without one)
  std::vector<std::string> file_names;  // N plain, distinct file names (no extension) made from them
};

// Reads and checks every array (shapes, finite values, face indices, 15 values per template
// triangle) before anything is decoded or written. InputError naming `what`, the array and, for
// a row of 'encodings', the item it decodes to. The template arrays may be missing only when
// `template_given` (decode --template).
EncodingFile parse_encoding_npz(const Npz& npz, const std::string& what, bool template_given = false);

// Builds the file (the keys above); names are stored one per line.
Npz encoding_to_npz(const EncodingFile& file, const std::string& layout);

}  // namespace bodymodel
