#include "model/part_pca.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace bodymodel {

std::vector<int> spatial_triangle_parts(const EncodingTemplate& tmpl, int parts, int iterations) {
  const Eigen::MatrixX3d& V = tmpl.rest_vertices();
  const Eigen::MatrixX3i& F = tmpl.faces();
  const int nf = static_cast<int>(F.rows());
  if (parts < 1 || parts > nf) throw InputError(fmt::format("parts: {} asked for a template of {} triangles", parts, nf));
  Eigen::MatrixX3d C(nf, 3);
  for (int f = 0; f < nf; ++f) C.row(f) = (V.row(F(f, 0)) + V.row(F(f, 1)) + V.row(F(f, 2))) / 3;
  // Farthest-point seeds: spread over the body whatever its pose.
  std::vector<Eigen::RowVector3d> centre{C.row(0)};
  Eigen::VectorXd nearest = (C.rowwise() - centre[0]).rowwise().squaredNorm();
  while (static_cast<int>(centre.size()) < parts) {
    Eigen::Index far = 0;
    nearest.maxCoeff(&far);
    centre.push_back(C.row(far));
    nearest = nearest.cwiseMin((C.rowwise() - centre.back()).rowwise().squaredNorm());
  }
  std::vector<int> label(nf, 0);
  for (int it = 0; it < iterations; ++it) {
    bool changed = false;
    for (int f = 0; f < nf; ++f) {
      int best = 0;
      for (int p = 1; p < parts; ++p)
        if ((C.row(f) - centre[p]).squaredNorm() < (C.row(f) - centre[best]).squaredNorm()) best = p;
      changed |= best != label[f];
      label[f] = best;
    }
    std::vector<Eigen::RowVector3d> sum(parts, Eigen::RowVector3d::Zero());
    std::vector<int> count(parts, 0);
    for (int f = 0; f < nf; ++f) {
      sum[label[f]] += C.row(f);
      ++count[label[f]];
    }
    for (int p = 0; p < parts; ++p)
      if (count[p] > 0) centre[p] = sum[p] / count[p];
    if (!changed && it > 0) break;
  }
  return label;
}

Pca part_wise_pca(const Pca& pca, const std::vector<int>& triangle_part, std::vector<int>* component_part) {
  const int D = pca.dimension(), N = static_cast<int>(pca.coefficients.rows());
  if (static_cast<int>(triangle_part.size()) * 15 != D)
    throw InputError(fmt::format("part_wise_pca: {} triangle parts for an encoding of {} values (15 per triangle)",
                                 triangle_part.size(), D));
  if (N < 2) throw InputError("part_wise_pca: the PCA keeps fewer than two training samples' coefficients");
  const int parts = triangle_part.empty() ? 0 : *std::max_element(triangle_part.begin(), triangle_part.end()) + 1;
  for (int p : triangle_part)
    if (p < 0) throw InputError("part_wise_pca: a triangle's part index is negative");
  const Eigen::MatrixXd X = pca.basis * pca.coefficients.transpose();  // D × N, centred samples
  std::vector<Eigen::VectorXd> columns;
  std::vector<double> variances;
  std::vector<int> part_of;
  for (int p = 0; p < parts; ++p) {
    std::vector<int> rows;
    for (int f = 0; f < static_cast<int>(triangle_part.size()); ++f)
      if (triangle_part[f] == p)
        for (int r = 0; r < 15; ++r) rows.push_back(15 * f + r);
    if (rows.empty()) continue;
    Eigen::MatrixXd Xp(rows.size(), N);
    for (size_t i = 0; i < rows.size(); ++i) Xp.row(i) = X.row(rows[i]);
    // The part's N × N Gram matrix (as fit_pca): its eigenvectors give the part's directions.
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Xp.transpose() * Xp / (N - 1));
    const double top = es.eigenvalues().maxCoeff();
    for (int k = N - 1; k >= 0; --k) {  // ascending eigenvalues: largest first
      const double lambda = es.eigenvalues()(k);
      if (!(lambda > 1e-10 * top)) continue;
      const Eigen::VectorXd u = Xp * es.eigenvectors().col(k) / std::sqrt((N - 1) * lambda);
      Eigen::VectorXd column = Eigen::VectorXd::Zero(D);
      for (size_t i = 0; i < rows.size(); ++i) column(rows[i]) = u(i);
      columns.push_back(std::move(column));
      variances.push_back(lambda);
      part_of.push_back(p);
    }
  }
  // All parts' components by decreasing variance, as a Pca's: the fit's leading-components
  // stage then starts with the largest motions of every part.
  std::vector<int> order(columns.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return variances[a] > variances[b]; });
  Pca out;
  out.mean = pca.mean;
  out.basis.resize(D, static_cast<Eigen::Index>(columns.size()));
  out.eigenvalues.resize(static_cast<Eigen::Index>(columns.size()));
  for (size_t k = 0; k < order.size(); ++k) {
    out.basis.col(k) = columns[order[k]];
    out.eigenvalues(k) = variances[order[k]];
  }
  out.coefficients = (out.basis.transpose() * X).transpose();
  if (component_part) {
    component_part->resize(order.size());
    for (size_t k = 0; k < order.size(); ++k) (*component_part)[k] = part_of[order[k]];
  }
  return out;
}

int PartModel::part_count() const {
  return triangle_part.empty() ? 0 : *std::max_element(triangle_part.begin(), triangle_part.end()) + 1;
}

PartModel build_part_model(const Pca& full, const EncodingTemplate& tmpl, int parts) {
  PartModel m;
  m.triangle_part = spatial_triangle_parts(tmpl, parts);
  m.pca = part_wise_pca(full, m.triangle_part, &m.component_part);
  return m;
}

}  // namespace bodymodel
