#include "model/body_model.h"

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include "model/format.h"
#include "model/pca_float.h"
#include <map>
#include <numeric>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/geometry.h"
#include "core/rotation.h"
#include "core/skeleton.h"

namespace bodymodel {

Encoding BodyModel::encode(const Eigen::MatrixX3d& V, const std::string& what) const {
  if (V.rows() != tmpl->vertex_count())
    throw InputError(fmt::format("{}: has {} vertices, the model's template has {} (is it registered "
                                 "to the model's template?)",
                                 what, V.rows(), tmpl->vertex_count()));
  tmpl->check_vertices(V, what);
  return bodymodel::encode(*tmpl, V, mean);
}

void BodyModel::check_topology(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                               const std::string& what) const {
  if (V.rows() != tmpl->vertex_count() || F.rows() != tmpl->triangle_count())
    throw InputError(fmt::format("{}: {} vertices and {} triangles, but the model's template has {} "
                                 "vertices and {} triangles: the mesh must be registered to the "
                                 "model's template",
                                 what, V.rows(), F.rows(), tmpl->vertex_count(), tmpl->triangle_count()));
  tmpl->check_faces(F, what);
  tmpl->check_vertices(V, what);
}

std::string ModelBuildSummary::report() const {
  return fmt::format(
      "{} scans of {} subjects encoded in {:.1f} s; shape model: {}; full model: {}; pose labels "
      "kept {} (dropped {} that never vary); PCA {:.1f} s",
      scans, subjects, encode_seconds, shape_pca.one_line(), full_pca.one_line(), pose_labels_kept,
      pose_labels_dropped, pca_seconds);
}

Eigen::VectorXd pose_label_values(const std::vector<LabelInfo>& labels,
                                  const std::vector<std::string>& bones, const Pose& pose) {
  std::map<std::string, int> index;
  for (size_t b = 0; b < bones.size(); ++b) index[bones[b]] = static_cast<int>(b);
  Eigen::VectorXd v = Eigen::VectorXd::Zero(labels.size());
  for (size_t i = 0; i < labels.size(); ++i) {
    const std::string& n = labels[i].name;  // pose:<bone>:rx
    if (n.rfind("pose:", 0) != 0 || n.size() < 9) continue;
    std::string bone = n.substr(5, n.size() - 8);
    int axis = n.back() - 'x';
    auto it = index.find(bone);
    if (it == index.end() || axis < 0 || axis > 2 || it->second >= static_cast<int>(pose.rotations.size()))
      continue;
    v(i) = rotation_vector_of(pose.rotations[it->second])(axis);
  }
  return v;
}

namespace {

// The leading components of `pca` (fitted with options at least as wide; `fitted` its summary)
// that `options` keeps: fit_pca's variance threshold and cap, against the total variance of all
// eigenvalues. For two models of the same samples.
Pca leading_components(const Pca& pca, const PcaSummary& fitted, const PcaOptions& options, PcaSummary* summary) {
  options.validate();
  const int available = pca.component_count();
  const double total = fitted.total_variance;
  const int cap = options.max_components > 0 ? std::min(options.max_components, available) : available;
  const double tiny = 1e-12 * std::max(total, 1e-300);
  int K = 0;
  double acc = 0;
  while (K < cap && pca.eigenvalues(K) > tiny) {
    acc += pca.eigenvalues(K);
    ++K;
    if (total > 0 && acc / total >= options.variance_threshold - 1e-12) break;
  }
  if (K == 0) K = std::min(1, available);
  Pca p;
  p.mean = pca.mean;
  p.basis = pca.basis.leftCols(K);
  p.eigenvalues = pca.eigenvalues.head(K);
  p.coefficients = pca.coefficients.leftCols(K);
  if (summary) {
    *summary = fitted;
    summary->components = K;
    summary->explained = total > 0 ? p.eigenvalues.sum() / total : 1.0;
  }
  return p;
}

SubModel fit_sub_model(Pca pca, const SemanticRegressionOptions& reg_options, const Eigen::MatrixXd& Y,
                       const std::vector<LabelInfo>& labels, std::vector<std::string> ids,
                       const std::vector<std::string>& basis_labels) {
  SubModel m;
  m.pca = std::move(pca);
  m.labels = Y;
  m.sample_ids = std::move(ids);
  m.regression = fit_semantic_regression(m.pca.coefficients, Y, labels, reg_options);
  std::vector<std::string> present;
  for (auto& n : basis_labels)
    if (m.regression.find(n) >= 0) present.push_back(n);
  m.semantic_basis = build_semantic_basis(m.regression, present, m.pca.coefficients);
  return m;
}

}  // namespace

BodyModel build_body_model(const ModelBuildInput& in, const ModelBuildOptions& o,
                           ModelBuildSummary* summary, const ProgressCallback& progress) {
  const int S = static_cast<int>(in.meshes.size());
  if (S == 0) throw InputError("model build: no meshes");
  if (static_cast<int>(in.scan_ids.size()) != S || static_cast<int>(in.subject_ids.size()) != S ||
      static_cast<int>(in.is_standard_pose.size()) != S || in.subject_label_values.rows() != S ||
      in.pose_label_values.rows() != S ||
      in.subject_label_values.cols() != static_cast<int>(in.subject_labels.size()) ||
      in.pose_label_values.cols() != static_cast<int>(in.pose_labels.size()))
    throw InputError("model build: the per-scan arrays have different lengths");
  const int nV = static_cast<int>(in.meshes[0].rows());
  for (int i = 0; i < S; ++i)
    if (in.meshes[i].rows() != nV)
      throw InputError(fmt::format("model build: scan '{}' has {} vertices, scan '{}' has {}: all "
                                   "meshes must share the template's topology",
                                   in.scan_ids[i], in.meshes[i].rows(), in.scan_ids[0], nV));
  std::vector<int> standard;
  for (int i = 0; i < S; ++i)
    if (in.is_standard_pose[i]) standard.push_back(i);
  const bool pose_only = standard.size() < 2 && o.allow_pose_only;
  if (standard.size() < 2 && !pose_only)
    throw InputError(fmt::format("model build: {} standard-pose scans, need at least 2 subjects in the "
                                 "standard pose for the shape model",
                                 standard.size()));
  if (pose_only && S < 2) throw InputError(fmt::format("model build: {} mesh(es), need at least 2", S));
  if (standard.empty()) standard.push_back(0);
  auto t0 = std::chrono::steady_clock::now();
  // Template rest shape: mean of the standard-pose meshes, rigidly aligned to the first.
  Eigen::MatrixX3d rest = Eigen::MatrixX3d::Zero(nV, 3);
  const Eigen::MatrixX3d& ref = in.meshes[standard[0]];
  for (int i : standard) rest += apply(fit_rigid_motion(in.meshes[i], ref), in.meshes[i]);
  rest /= static_cast<double>(standard.size());
  BodyModel model;
  model.tmpl = std::make_shared<EncodingTemplate>(rest, in.F);

  // Absolute encodings (parallel), the mean, then relative values into the data matrix. The
  // matrix is float32 (half the memory of doubles: 2 000 bodies of 26 756 triangles are 3.2 GB
  // instead of 6.4); the mean and the PCA are accumulated in double (model/pca.h). float32
  // keeps 7 significant digits of each encoding value, and the model file stores the bases as
  // float32 anyway.
  const int D = model.tmpl->encoding_size();
  Eigen::MatrixXf X(D, S);
  std::atomic<int> done{0};
  std::mutex mtx;
  tbb::enumerable_thread_specific<Eigen::VectorXd> partial_sums([&] { return Eigen::VectorXd::Zero(D); });
  tbb::parallel_for(0, S, [&](int i) {
    const Eigen::VectorXd a = encode_absolute(*model.tmpl, in.meshes[i]);
    partial_sums.local() += a;
    X.col(i) = a.cast<float>();
    int d = ++done;
    std::lock_guard<std::mutex> lock(mtx);
    report_progress(progress, 0.6 * d / S, in.scan_ids[i]);
  });
  Eigen::VectorXd sum_abs = Eigen::VectorXd::Zero(D);
  for (const auto& ps : partial_sums) sum_abs += ps;
  model.mean = EncodingMean::from_values(sum_abs / S);
  tbb::parallel_for(0, S, [&](int i) {
    const Eigen::VectorXd a = X.col(i).cast<double>();
    X.col(i) = relative_to(model.mean, a).values.cast<float>();
  });
  auto t1 = std::chrono::steady_clock::now();

  // Pose labels that vary.
  std::vector<int> pose_keep;
  for (int j = 0; j < static_cast<int>(in.pose_labels.size()); ++j) {
    Eigen::VectorXd c = in.pose_label_values.col(j);
    double m = c.mean();
    double sd = std::sqrt((c.array() - m).square().sum() / std::max(1, S - 1));
    if (sd >= o.min_pose_label_stddev) pose_keep.push_back(j);
  }
  const int Ls = static_cast<int>(in.subject_labels.size());
  const int Lp = static_cast<int>(pose_keep.size());
  std::vector<LabelInfo> full_labels = in.subject_labels;
  Eigen::MatrixXd Yfull(S, Ls + Lp);
  Yfull.leftCols(Ls) = in.subject_label_values;
  for (int j = 0; j < Lp; ++j) {
    full_labels.push_back(in.pose_labels[pose_keep[j]]);
    Yfull.col(Ls + j) = in.pose_label_values.col(pose_keep[j]);
  }

  ModelBuildSummary sum;
  std::vector<int> all_columns(S);
  std::iota(all_columns.begin(), all_columns.end(), 0);
  const std::vector<int>& shape_columns = pose_only ? all_columns : standard;
  const PcaOptions& shape_options = pose_only ? o.full_pca : o.shape_pca;
  // When the shape model's samples are all the meshes (one person in many poses; a population
  // of one standard-pose mesh per person) the two PCAs share one eigen-decomposition: it is
  // computed once, keeping what the wider of the two options keeps, and each model takes its
  // leading components (the Gram matrix and the basis are the costly part at thousands of meshes).
  Pca shape_pca, full_pca;
  if (shape_columns == all_columns) {
    PcaOptions wide = o.full_pca;
    wide.variance_threshold = std::max(shape_options.variance_threshold, o.full_pca.variance_threshold);
    wide.max_components = shape_options.max_components < 0 || o.full_pca.max_components < 0
                              ? -1
                              : std::max(shape_options.max_components, o.full_pca.max_components);
    report_progress(progress, 0.7, "PCA");
    PcaSummary wide_summary;
    Pca both = fit_pca(X, all_columns, wide, &wide_summary);
    X.resize(0, 0);
    shape_pca = leading_components(both, wide_summary, shape_options, &sum.shape_pca);
    full_pca = leading_components(both, wide_summary, o.full_pca, &sum.full_pca);
  } else {
    report_progress(progress, 0.7, "shape PCA");
    shape_pca = fit_pca(X, shape_columns, shape_options, &sum.shape_pca);
    report_progress(progress, 0.85, "full PCA");
    full_pca = fit_pca(X, all_columns, o.full_pca, &sum.full_pca);
    X.resize(0, 0);
  }
  report_progress(progress, 0.95, "regression");
  model.full = fit_sub_model(std::move(full_pca), o.regression, Yfull, full_labels, in.scan_ids, o.semantic_basis_labels);
  if (pose_only) {
    model.shape = model.full;  // one person: no shape variation to model; the pose model serves as both
  } else {
    Eigen::MatrixXd Ys(standard.size(), Ls);
    std::vector<std::string> subject_ids;
    for (size_t k = 0; k < standard.size(); ++k) {
      Ys.row(k) = in.subject_label_values.row(standard[k]);
      subject_ids.push_back(in.subject_ids[standard[k]]);
    }
    model.shape = fit_sub_model(std::move(shape_pca), o.regression, Ys, in.subject_labels, subject_ids, o.semantic_basis_labels);
  }
  auto t2 = std::chrono::steady_clock::now();
  report_progress(progress, 1.0, "done");

  sum.scans = S;
  sum.subjects = pose_only ? 1 : static_cast<int>(standard.size());
  sum.pose_labels_kept = Lp;
  sum.pose_labels_dropped = static_cast<int>(in.pose_labels.size()) - Lp;
  sum.encode_seconds = std::chrono::duration<double>(t1 - t0).count();
  sum.pca_seconds = std::chrono::duration<double>(t2 - t1).count();
  model.metadata = {{"format", "bodymodel-model"},
                    {"format_version", kModelFormatVersion},
                    {"scans", S},
                    {"subjects", sum.subjects},
                    {"vertices", nV},
                    {"triangles", in.F.rows()},
                    {"shape_components", model.shape.component_count()},
                    {"full_components", model.full.component_count()},
                    {"shape_variance_threshold", o.shape_pca.variance_threshold},
                    {"full_variance_threshold", o.full_pca.variance_threshold},
                    {"shape_explained", sum.shape_pca.explained},
                    {"full_explained", sum.full_pca.explained},
                    {"shape_total_variance", sum.shape_pca.total_variance},
                    {"full_total_variance", sum.full_pca.total_variance},
                    {"shape_model", pose_only ? "full" : "standard-pose scans"},
                    {"units", "mm"}};
  if (summary) *summary = sum;
  return model;
}

}  // namespace bodymodel
