// The statistical body model (Hasler et al. 2009 §4, docs/method.md §4.1): relative rotation
// encodings of registered meshes, PCA'd twice —
//   * the SHAPE-ONLY model: one standard-pose scan per subject (random generation, morphing by
//     height/weight/..., handle editing);
//   * the FULL model: every scan, pose and shape (pose morphing, §5.4);
// each with a semantic regression of its labels (eq. 10) and the §4.1 semantic basis.
//
// Coordinates: a body's encoding x (15·#F, relative to the model's encoding mean, see
// encoding/relative_rotation_encoding.h) is x ≈ pca.mean + pca.basis · c; c (K numbers) are
// the body's coefficients in that sub-model. Morphing changes c by z and the encoding by
// basis · z, so whatever of the body the model cannot represent is kept.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/progress.h"
#include "encoding/relative_rotation_encoding.h"
#include "model/model_rig.h"
#include "model/part_pca.h"
#include "model/pca.h"
#include "model/semantic.h"

namespace bodymodel {

// 2: shape_basis and full_basis stored as float32 (version 1 stored everything as float64;
// still read).
inline constexpr int kModelFormatVersion = 2;
// 3: the bases quantised to 8 or 16 bits (model/model_file.h, model/quantise.h); written only
// when asked for, so float32 files stay readable by programs that predate it.
inline constexpr int kQuantisedModelFormatVersion = 3;
// 4: quantised with per-column widths other than 8 and 16 bits, bit-packed (model/model_file.h).
inline constexpr int kPackedModelFormatVersion = 4;

// One PCA model with its labels.
struct SubModel {
  Pca pca;                          // of the encodings (D = 15·#F)
  SemanticRegression regression;    // labels on pca coefficients
  SemanticBasis semantic_basis;     // §4.1
  std::vector<std::string> sample_ids;  // N: subject ids (shape model) or scan ids (full model)
  Eigen::MatrixXd labels;           // N by L label values of the training samples (NaN = unknown)
  int component_count() const { return pca.component_count(); }
};

struct BodyModel {
  std::shared_ptr<const EncodingTemplate> tmpl;  // rest vertices (mm) and faces
  std::shared_ptr<const EncodingMean> mean;      // encoding mean of all scans
  SubModel shape;                                // standard-pose scans, one per subject
  SubModel full;                                 // all scans
  ModelRig rig;                                  // may be empty
  // Optional (`build --parts`): a part-wise PCA of the full model's training samples, used by
  // `fit` and `eval-model` in place of the full model's PCA; load_model refuses such a file
  // unless asked to read it (other verbs cannot use it).
  PartModel parts;
  nlohmann::json metadata;                       // build information (format version, counts, ...)

  // Encoding of V (#V by 3, mm) relative to the model's mean; InputError if the vertex count
  // is not the model's (names `what`).
  Encoding encode(const Eigen::MatrixX3d& V, const std::string& what = "mesh") const;
  // Encoding of encoding values x (relative to the model's mean).
  Encoding encoding_of(Eigen::VectorXd x) const { return Encoding{std::move(x), mean}; }
  // Throws InputError if F is not the model's topology (names `what`).
  void check_topology(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const std::string& what) const;
};

// What to build from: registered meshes (template topology) with labels.
struct ModelBuildInput {
  Eigen::MatrixX3i F;                      // #F by 3, shared by all meshes
  std::vector<Eigen::MatrixX3d> meshes;    // #scans, each #V by 3 (mm)
  std::vector<std::string> scan_ids;       // #scans
  std::vector<std::string> subject_ids;    // #scans: the subject of each scan
  std::vector<char> is_standard_pose;      // #scans: 1 for the subject's standard-pose scan
  std::vector<LabelInfo> subject_labels;   // L_s label names and units (statistics filled later)
  Eigen::MatrixXd subject_label_values;    // #scans by L_s (the subject's values, per scan)
  std::vector<LabelInfo> pose_labels;      // L_p joint-angle labels ("pose:<bone>:rx|ry|rz", rad)
  Eigen::MatrixXd pose_label_values;       // #scans by L_p
};

struct ModelBuildOptions {
  PcaOptions shape_pca{0.995, -1};  // shape: keep nearly everything (few subjects)
  PcaOptions full_pca{0.99, -1};
  SemanticRegressionOptions regression;
  // Pose labels whose standard deviation over the scans is below this are dropped (bones the
  // data never moves carry no information), radians.
  double min_pose_label_stddev = 0.02;
  // Labels whose directions come first in the semantic basis (those present are used).
  std::vector<std::string> semantic_basis_labels = {"height_cm", "weight_kg", "sex", "age_years",
                                                    "muscle", "body_fat_pct"};
  // With fewer than two standard-pose scans (one person in many poses, e.g. SCAPE): build the
  // full (pose) model and use it as the shape model too, instead of refusing. The metadata
  // says so ("shape_model": "full").
  bool allow_pose_only = false;
};

struct ModelBuildSummary {
  int scans = 0, subjects = 0;
  PcaSummary shape_pca, full_pca;
  int pose_labels_kept = 0, pose_labels_dropped = 0;
  double encode_seconds = 0, pca_seconds = 0;
  std::string report() const;
};

// Builds both models. The template rest shape is the vertex mean of the standard-pose meshes
// (each rigidly aligned to the first). Throws InputError when no subject has a standard-pose
// scan, sizes disagree or a mesh does not have the common vertex count.
BodyModel build_body_model(const ModelBuildInput& input, const ModelBuildOptions& options = {},
                           ModelBuildSummary* summary = nullptr, const ProgressCallback& progress = {});

// The pose-label values (for `labels`, names "pose:<bone>:rx|ry|rz") of a pose of a skeleton
// with bone names `bones`; labels whose bone is not in the skeleton get 0.
Eigen::VectorXd pose_label_values(const std::vector<LabelInfo>& labels,
                                  const std::vector<std::string>& bones, const struct Pose& pose);

}  // namespace bodymodel
