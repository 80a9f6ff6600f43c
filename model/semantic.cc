#include "model/semantic.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <cmath>
#include "model/format.h"

#include "core/error.h"
#include "regression/linear.h"

namespace bodymodel {

int SemanticRegression::find(const std::string& name) const {
  for (int i = 0; i < label_count(); ++i)
    if (labels[i].name == name) return i;
  return -1;
}

std::string SemanticRegression::names() const {
  std::string s;
  for (const auto& l : labels) {
    if (l.name.rfind("pose:", 0) == 0) continue;  // joint angles are many; listed elsewhere
    if (!s.empty()) s += ", ";
    s += l.name;
  }
  return s;
}

int SemanticRegression::index(const std::string& name) const {
  int i = find(name);
  if (i < 0)
    throw InputError(fmt::format("unknown label '{}'; the model's labels are: {}", name, names()));
  return i;
}

Eigen::VectorXd SemanticRegression::predict(const Eigen::VectorXd& c) const {
  if (c.size() != gradients.rows())
    throw InputError(fmt::format("label prediction: expected {} coefficients, got {}",
                                 gradients.rows(), c.size()));
  return offsets + gradients.transpose() * c;
}

SemanticRegression fit_semantic_regression(const Eigen::MatrixXd& C, const Eigen::MatrixXd& Y,
                                           std::vector<LabelInfo> labels,
                                           const SemanticRegressionOptions& options) {
  const int N = static_cast<int>(C.rows()), K = static_cast<int>(C.cols());
  const int L = static_cast<int>(labels.size());
  if (Y.rows() != N || Y.cols() != L)
    throw InputError(fmt::format("semantic regression: labels are {}×{}, expected {}×{}", Y.rows(),
                                 Y.cols(), N, L));
  SemanticRegression r;
  r.offsets.resize(L);
  r.gradients.resize(K, L);
  double mean_var = 0;
  if (N > 1) mean_var = (C.rowwise() - C.colwise().mean()).squaredNorm() / ((N - 1.0) * std::max(K, 1));
  for (int l = 0; l < L; ++l) {
    std::vector<int> rows;
    for (int i = 0; i < N; ++i)
      if (std::isfinite(Y(i, l))) rows.push_back(i);
    if (rows.size() < 2)
      throw InputError(fmt::format("semantic regression: label '{}' has {} known values, need ≥ 2",
                                   labels[l].name, rows.size()));
    Eigen::MatrixXd X(rows.size(), K);
    Eigen::VectorXd y(rows.size());
    for (size_t i = 0; i < rows.size(); ++i) {
      X.row(i) = C.row(rows[i]);
      y(i) = Y(rows[i], l);
    }
    // Eq. 10 (regression/linear.h), with a tiny ridge for stability. A failure names the label:
    // huge values (1e308) overflow the solve and the statistics, and a model holding them is
    // one no reader takes back.
    const auto refuse = [&](const std::string& why) {
      return InputError(fmt::format("semantic regression: label '{}' (values {:.4g} … {:.4g}): {}; check its "
                                    "column in the labels table",
                                    labels[l].name, y.minCoeff(), y.maxCoeff(), why));
    };
    LinearFit fit;
    try {
      fit = fit_linear(X, y, options.relative_ridge * mean_var * rows.size());
    } catch (const NumericalError&) {
      throw refuse("the regression produced non-finite coefficients");
    }
    if (!std::isfinite(fit.offset) || !fit.gradient.allFinite())
      throw refuse("the regression produced non-finite coefficients");
    r.offsets(l) = fit.offset;
    r.gradients.col(l) = fit.gradient;
    LabelInfo& info = labels[l];
    info.mean = y.mean();
    info.stddev = std::sqrt((y.array() - info.mean).square().sum() / std::max<double>(1, y.size() - 1));
    info.min = y.minCoeff();
    info.max = y.maxCoeff();
    if (!std::isfinite(info.mean) || !std::isfinite(info.stddev))
      throw refuse("its mean or spread is not finite");
  }
  r.labels = std::move(labels);
  return r;
}

Eigen::VectorXd constrained_change(const Eigen::MatrixXd& S, const Eigen::VectorXd& delta,
                                   const ConstrainedChangeOptions& options) {
  if (S.cols() != delta.size())
    throw InputError(fmt::format("constrained change: {} directions but {} target changes", S.cols(),
                                 delta.size()));
  if (S.cols() == 0) return Eigen::VectorXd::Zero(S.rows());
  if (!S.allFinite() || !delta.allFinite())
    throw InputError("constrained change: non-finite directions or targets");
  if (options.metric.size() != 0) {
    // z = D y with D = diag(√w): min ‖y‖ subject to (D S)ᵀ y = Δ is min Σ z²/w subject to Sᵀ z = Δ.
    if (options.metric.size() != S.rows() || !(options.metric.array() > 0).all())
      throw InputError(fmt::format("constrained change: metric of {} values for {} coefficients (all must be > 0)",
                                   options.metric.size(), S.rows()));
    ConstrainedChangeOptions euclidean = options;
    euclidean.metric.resize(0);
    const Eigen::VectorXd d = options.metric.cwiseSqrt();
    return d.cwiseProduct(constrained_change(d.asDiagonal() * S, delta, euclidean));
  }
  // z = S (SᵀS)⁺ Δ through the SVD of Sᵀ = U Σ Vᵀ: z = V Σ⁺ Uᵀ Δ (minimum-norm solution).
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(S.transpose(), Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd& sv = svd.singularValues();
  if (sv.size() == 0 || sv(0) == 0) return Eigen::VectorXd::Zero(S.rows());
  const double mu = options.damping * sv(0) * sv(0);
  Eigen::VectorXd w = svd.matrixU().transpose() * delta;
  for (int i = 0; i < sv.size(); ++i) {
    if (sv(i) <= options.rcond * sv(0))
      w(i) = 0;
    else
      w(i) *= sv(i) / (sv(i) * sv(i) + mu);
  }
  return svd.matrixV() * w;
}

SemanticBasis build_semantic_basis(const SemanticRegression& regression,
                                   const std::vector<std::string>& label_names,
                                   const Eigen::MatrixXd& C) {
  const int K = static_cast<int>(regression.gradients.rows());
  if (C.cols() != K)
    throw InputError(fmt::format("semantic basis: coefficients have {} columns, expected {}", C.cols(), K));
  SemanticBasis b;
  std::vector<Eigen::VectorXd> q;
  for (const auto& name : label_names) {
    if (static_cast<int>(q.size()) >= K) break;
    Eigen::VectorXd v = regression.gradients.col(regression.index(name));
    const double n0 = v.norm();
    if (n0 == 0) continue;
    for (int pass = 0; pass < 2; ++pass)  // Gram–Schmidt, twice for stability
      for (const auto& u : q) v -= u.dot(v) * u;
    if (v.norm() < 1e-6 * n0) continue;  // dependent on the previous directions
    q.push_back(v.normalized());
    b.semantic_labels.push_back(name);
  }
  const int m = static_cast<int>(q.size());
  Eigen::MatrixXd Q(K, m);
  for (int i = 0; i < m; ++i) Q.col(i) = q[i];
  // Remainder: the data with the semantic directions projected out, PCA'd (K×K covariance).
  Eigen::MatrixXd Cc = C.rowwise() - C.colwise().mean();
  Eigen::MatrixXd P = Eigen::MatrixXd::Identity(K, K) - Q * Q.transpose();
  Eigen::MatrixXd R = Cc * P;
  Eigen::MatrixXd cov = R.transpose() * R / std::max<double>(1, C.rows() - 1);
  // Add a tiny multiple of P so directions with no data variance still span the complement.
  cov += 1e-12 * std::max(cov.trace(), 1.0) * P;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(cov);
  Eigen::MatrixXd E = es.eigenvectors().rowwise().reverse();  // descending
  b.basis.resize(K, K);
  b.basis.leftCols(m) = Q;
  // The top K − m eigenvectors lie in the complement (the semantic span has ~0 eigenvalue).
  Eigen::MatrixXd rem = P * E.leftCols(K - m);
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(rem);
  Eigen::MatrixXd rq = qr.householderQ() * Eigen::MatrixXd::Identity(K, K - m);
  rq = P * rq;  // stay exactly in the complement
  for (int i = 0; i < K - m; ++i) rq.col(i).normalize();
  b.basis.rightCols(K - m) = rq;
  b.variances.resize(K);
  for (int i = 0; i < K; ++i) {
    Eigen::VectorXd proj = Cc * b.basis.col(i);
    b.variances(i) = proj.squaredNorm() / std::max<double>(1, C.rows() - 1);
  }
  return b;
}

}  // namespace bodymodel
