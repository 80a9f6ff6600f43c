#include "model/shape_preview.h"

#include <fmt/format.h>

#include "core/error.h"

namespace bodymodel {

ShapePreview::ShapePreview(const ShapeMorpher& morpher, const Eigen::VectorXd& x0, const std::atomic<bool>* stop) {
  const Pca& pca = morpher.model().shape.pca;
  const int K = pca.component_count();
  V0_ = morpher.decode(x0);
  const Eigen::Index n = V0_.size();
  J_.resize(n, K);
  for (int k = 0; k < K; ++k) {
    if (stop && *stop) return;
    const double s = std::sqrt(std::max(pca.eigenvalues(k), 1e-12));
    const Eigen::MatrixX3d plus = morpher.decode(x0 + s * pca.basis.col(k));
    if (stop && *stop) return;
    const Eigen::MatrixX3d minus = morpher.decode(x0 - s * pca.basis.col(k));
    const Eigen::MatrixX3d d = (plus - minus) / (2 * s);
    for (Eigen::Index v = 0; v < d.rows(); ++v)
      for (int c = 0; c < 3; ++c) J_(3 * v + c, k) = static_cast<float>(d(v, c));
  }
  ready_ = true;
}

Eigen::MatrixX3d ShapePreview::operator()(const Eigen::VectorXd& z) const {
  if (!ready_) throw InputError("shape preview: not built");
  if (z.size() != J_.cols())
    throw InputError(fmt::format("shape preview: {} coefficients, the model has {}", z.size(), J_.cols()));
  const Eigen::VectorXf d = J_ * z.cast<float>();
  Eigen::MatrixX3d V = V0_;
  for (Eigen::Index v = 0; v < V.rows(); ++v)
    for (int c = 0; c < 3; ++c) V(v, c) += d(3 * v + c);
  return V;
}

Eigen::VectorXd ShapePreview::first_change(const SubModel& shape, const std::vector<LabelCondition>& conditions,
                                           const Eigen::VectorXd& c0) {
  const SemanticRegression& reg = shape.regression;
  const int m = static_cast<int>(conditions.size());
  if (m == 0) return Eigen::VectorXd::Zero(shape.component_count());
  const Eigen::VectorXd pred = reg.predict(c0);
  Eigen::MatrixXd S(shape.component_count(), m);
  Eigen::VectorXd delta(m);
  for (int i = 0; i < m; ++i) {
    const LabelCondition& c = conditions[static_cast<size_t>(i)];
    if (c.keep || c.lo != c.hi) throw InputError("shape preview: only exact label values (" + c.label + ")");
    const int idx = reg.index(c.label);
    S.col(i) = reg.gradients.col(idx);
    delta(i) = c.lo - pred(idx);
  }
  return constrained_change(S, delta, MorphOptions{}.change);
}

}  // namespace bodymodel
