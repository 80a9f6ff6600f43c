// Semantic regression, constrained morphing and the semantic basis (Hasler et al. 2009 §4,
// §4.1; docs/method.md §4.2–§4.4). Everything here works in PCA-coefficient space (K numbers per
// body).
//
//  * Eq. 10: per label l (height, weight, a joint angle, ...) an affine fit
//    l ≈ o + s·c over the training subjects' coefficients c; s is the label's morph direction.
//  * Eq. 11: several simultaneous label changes Δ_i (some 0 = "keep this label") are met by the
//    minimum-norm change z with s_iᵀ z = Δ_i for all i ("change the subject as little as
//    possible"); because the PCA basis is orthonormal, ‖z‖ is also the change of the encoding.
//  * §4.1: the semantic directions, Gram–Schmidt orthonormalised, plus a PCA of what remains
//    of the data after projecting them out, form a new orthonormal basis in which a label is
//    held by fixing its coordinate and varying only the remainder.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace bodymodel {

// What a label is and how it is distributed in the training data.
struct LabelInfo {
  std::string name;   // "height_cm", "weight_kg", "sex" (0 female, 1 male), "pose:upperarm01.L:rx"
  std::string unit;   // "cm", "kg", "%", "years", "rad", "" ...
  double mean = 0, stddev = 0, min = 0, max = 0;  // over the training samples
};

// Eq. 10 for every label at once.
struct SemanticRegression {
  std::vector<LabelInfo> labels;  // L
  Eigen::VectorXd offsets;        // L, o per label (label unit)
  Eigen::MatrixXd gradients;      // K by L, s per label (label unit per coefficient unit)

  int label_count() const { return static_cast<int>(labels.size()); }
  // Index of the label called `name`; InputError listing the valid names when unknown.
  int index(const std::string& name) const;
  int find(const std::string& name) const;  // −1 when unknown
  // Predicted labels (L) for coefficients c (K).
  Eigen::VectorXd predict(const Eigen::VectorXd& c) const;
  // Comma-separated label names (for error messages).
  std::string names() const;
};

struct SemanticRegressionOptions {
  // Ridge penalty on s relative to the mean coefficient variance (0 = eq. 10 exactly). A
  // small ridge keeps directions stable when subjects are few.
  double relative_ridge = 1e-6;
};

// C N by K coefficients of the training samples; Y N by L label values (NaN = unknown for that
// sample: the sample is left out of that label's fit); labels L (names/units; statistics are
// filled in here). Throws InputError on mismatched sizes, a label with < 2 known values, or a
// label whose regression or statistics are not finite (values too large: names the label).
SemanticRegression fit_semantic_regression(const Eigen::MatrixXd& C, const Eigen::MatrixXd& Y,
                                           std::vector<LabelInfo> labels,
                                           const SemanticRegressionOptions& options = {});

struct ConstrainedChangeOptions {
  // Directions whose singular value is below rcond · (largest) are treated as dependent and
  // dropped (the constraints are then met in the least-squares sense).
  double rcond = 1e-8;
  // Tikhonov damping relative to the largest squared singular value: trades exactness of the
  // constraints against the size of the change when there are nearly as many constraints as
  // components (pose morphing constrains every joint angle). 0 = exact minimum norm (eq. 11).
  double damping = 0;
  // K positive values w: minimise Σ z_k² / w_k instead of ‖z‖². With the PCA eigenvalues this is
  // the most likely change under the model's Gaussian (the conditional mean of the body given
  // the label changes) rather than the smallest one. Empty = Euclidean, eq. 11 as in the paper.
  Eigen::VectorXd metric;
};

// Eq. 11: minimum-norm z (K) with Sᵀ z = delta. S K by m (columns = gradients s_i), delta m.
Eigen::VectorXd constrained_change(const Eigen::MatrixXd& S, const Eigen::VectorXd& delta,
                                   const ConstrainedChangeOptions& options = {});

// §4.1 semantic basis in coefficient space.
struct SemanticBasis {
  std::vector<std::string> semantic_labels;  // m labels whose directions come first
  Eigen::MatrixXd basis;        // K by K orthonormal: [Gram–Schmidt of s_i (m) | remainder PCA]
  Eigen::VectorXd variances;    // K, variance of the training data along each column
  int semantic_count() const { return static_cast<int>(semantic_labels.size()); }
};

// Builds the basis from the gradients of `label_names` (in that order; a direction dependent
// on the previous ones is skipped) and the training coefficients C (N by K).
SemanticBasis build_semantic_basis(const SemanticRegression& regression,
                                   const std::vector<std::string>& label_names,
                                   const Eigen::MatrixXd& C);

}  // namespace bodymodel
