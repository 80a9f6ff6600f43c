// A part-wise pose model (docs/model.md §5.4). The relative rotation encoding has 15 values per
// triangle; a global PCA of a few dozen poses of one person offers only as many directions for
// the whole body, so a held-out pose whose limbs combine as no training pose's do lies outside
// its span. Here the triangles are split into parts and each part gets its own PCA of the
// training samples' encodings restricted to its rows: the parts' poses then combine freely
// (the decoder joins them, as it joins any encoding), with as many components per part as the
// global model has in all. The result is an ordinary Pca (orthonormal columns, each zero outside
// its part), so ModelFitter fits it as it fits the global one; the fit's cost grows with the
// component count.
#pragma once

#include <vector>

#include "encoding/relative_rotation_encoding.h"
#include "model/pca.h"

namespace bodymodel {

// Parts by k-means of the template's triangle centroids (rest pose), seeded by farthest-point
// sampling from triangle 0: deterministic. Returns #F part indices in [0, parts). A purely
// spatial split: parts need not follow the joints. Throws InputError unless 1 ≤ parts ≤ #F.
std::vector<int> spatial_triangle_parts(const EncodingTemplate& tmpl, int parts, int iterations = 30);

// The part-wise PCA of the training samples `pca` was built from (their encodings are
// pca.mean + pca.basis · coefficients(i)ᵀ; exact when the PCA kept every component): per part,
// the principal directions of those encodings restricted to the part's rows (components whose
// variance is below 1e-10 of the part's largest dropped), all parts' components together by
// decreasing variance. Its mean is pca.mean and its coefficients the samples'.
// Throws InputError when triangle_part's size is not dimension / 15 or a part index is < 0.
// component_part (optional): the part of each output component.
Pca part_wise_pca(const Pca& pca, const std::vector<int>& triangle_part, std::vector<int>* component_part = nullptr);

// A part-wise pose model as `build --parts` stores it beside the global models (model file keys
// parts_*, model/model_file.h): the part of every triangle and the part-wise PCA, whose
// components are each zero outside one part (component_part), its mean the full model's and its
// coefficients those of the full model's training samples.
struct PartModel {
  std::vector<int> triangle_part;   // #F, in [0, part_count())
  std::vector<int> component_part;  // K
  Pca pca;
  bool empty() const { return triangle_part.empty(); }
  int part_count() const;
};

// The part-wise model of the samples `full` was built from (part_wise_pca of `parts` spatial
// parts, spatial_triangle_parts): what `build --parts` writes and `eval-model --parts` evaluates.
PartModel build_part_model(const Pca& full, const EncodingTemplate& tmpl, int parts);

}  // namespace bodymodel
