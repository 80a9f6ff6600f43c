#include "encoding/encoding_file.h"

#include <cmath>
#include <cstdio>
#include <sstream>

#include "core/error.h"
#include "core/io/file_names.h"

namespace bodymodel {

namespace {

std::string non_finite(double x) { return std::isnan(x) ? "NaN" : "infinity"; }

std::string item_name(Eigen::Index row, const std::vector<std::string>& names) {
  return "row " + std::to_string(row) + " ('" + names[static_cast<size_t>(row)] + "')";
}

}  // namespace

EncodingFile parse_encoding_npz(const Npz& npz, const std::string& what, bool template_given) {
  EncodingFile e;
  const bool has_template = npz.has("template_vertices") || npz.has("template_faces");
  if (has_template || !template_given) {
    const Eigen::MatrixXd V = npz.matrix("template_vertices");
    if (V.cols() != 3)
      throw InputError(what + ": 'template_vertices' has " + std::to_string(V.cols()) + " columns, expected 3");
    for (Eigen::Index r = 0; r < V.rows(); ++r)
      for (Eigen::Index c = 0; c < 3; ++c)
        if (!std::isfinite(V(r, c)))
          throw InputError(what + ": 'template_vertices' holds " + non_finite(V(r, c)) + " at row " +
                           std::to_string(r) + ", column " + std::to_string(c) + ", expected finite coordinates");
    const Eigen::MatrixXi F = npz.int_matrix("template_faces");
    if (F.cols() != 3 || F.rows() == 0)
      throw InputError(what + ": 'template_faces' is " + std::to_string(F.rows()) + "×" + std::to_string(F.cols()) +
                       ", expected #F×3 triangles");
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      for (Eigen::Index k = 0; k < 3; ++k)
        if (F(f, k) < 0 || F(f, k) >= V.rows())
          throw InputError(what + ": 'template_faces' row " + std::to_string(f) + " names vertex " +
                           std::to_string(F(f, k)) + ", expected 0.." + std::to_string(V.rows() - 1));
    e.template_vertices = V;
    e.template_faces = F;
  }
  e.encodings = npz.matrix("encodings");
  e.mean = npz.vector("mean");
  const Eigen::Index D = e.template_faces.rows() > 0 ? 15 * e.template_faces.rows() : e.mean.size();
  if (e.encodings.cols() != D)
    throw InputError(what + ": 'encodings' has " + std::to_string(e.encodings.cols()) + " columns, the template needs " +
                     std::to_string(D) + " (15 per triangle)");
  if (e.mean.size() != D || D % 15 != 0)
    throw InputError(what + ": 'mean' has " + std::to_string(e.mean.size()) + " values, expected " + std::to_string(D) +
                     " (15 per triangle)");
  for (Eigen::Index k = 0; k < e.mean.size(); ++k)
    if (!std::isfinite(e.mean(k)))
      throw InputError(what + ": 'mean' holds " + non_finite(e.mean(k)) + " at value " + std::to_string(k) +
                       " (triangle " + std::to_string(k / 15) + "), expected finite values");
  if (npz.has("names")) {
    std::istringstream in(npz.text("names"));
    for (std::string line; std::getline(in, line);) {
      if (!line.empty() && line.back() == '\r') line.pop_back();
      if (!line.empty()) e.names.push_back(line);
    }
  }
  e.names.resize(std::min(e.names.size(), static_cast<size_t>(e.encodings.rows())));
  while (e.names.size() < static_cast<size_t>(e.encodings.rows())) {
    char name[32];
    std::snprintf(name, sizeof name, "decoded_%03zu", e.names.size());
    e.names.push_back(name);
  }
  e.file_names = unique_file_names(e.names, "decoded");
  // Every row is checked before anything is decoded: a bad row names the file and the item (by
  // its file name: a stored name may hold control characters).
  for (Eigen::Index i = 0; i < e.encodings.rows(); ++i)
    for (Eigen::Index k = 0; k < e.encodings.cols(); ++k)
      if (!std::isfinite(e.encodings(i, k)))
        throw InputError(what + ": 'encodings' " + item_name(i, e.file_names) + " holds " +
                         non_finite(e.encodings(i, k)) + " at value " + std::to_string(k) + " (triangle " +
                         std::to_string(k / 15) + "), expected finite values");
  return e;
}

Npz encoding_to_npz(const EncodingFile& file, const std::string& layout) {
  Npz npz;
  npz.put("encodings", file.encodings);
  npz.put("mean", file.mean);
  npz.put("template_vertices", Eigen::MatrixXd(file.template_vertices));
  npz.put("template_faces", Eigen::MatrixXi(file.template_faces));
  std::string names;
  for (const auto& n : file.names) names += n + "\n";
  npz.put_text("names", names);
  npz.put_text("layout", layout);
  return npz;
}

}  // namespace bodymodel
