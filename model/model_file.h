// The model file: a NumPy .npz archive (core/io/npz.h) that `np.load` opens.
//
// FORMAT (format_version 2). Matrices are float64 in C order except shape_basis and full_basis,
// which are float32 (they are nearly the whole file; orthonormal columns with 7 significant
// digits change a decoded body by far less than 0.01 mm). Version 1 files (the same keys, all
// float64) are still read; other versions are refused with an error naming the version.
// Members are deflated (numpy's savez_compressed layout; np.load reads either).
// D = 15·#F encoding values,
// K_s / K_f shape / full components, N_s subjects, N_f scans, L_s / L_f labels.
//   metadata                 JSON text: {"format": "bodymodel-model", "format_version": 2, ...}
//   format_version           scalar 2
//   template_vertices        #V by 3, mm (rest shape: mean of the standard-pose scans)
//   template_faces           #F by 3 int (vertex indices, counter-clockwise from outside)
//   encoding_mean            D, absolute relative-rotation-encoding mean (see
//                            encoding/relative_rotation_encoding.h for the layout)
//   shape_mean, shape_basis  D and D by K_s: encoding x ≈ shape_mean + shape_basis · c
//   shape_eigenvalues        K_s, variance of each coefficient
//   shape_coefficients       N_s by K_s, coefficients of the training subjects
//   labels                   N_s by L_s label values of the training subjects (NaN = unknown)
//   label_names              JSON text: list of L_s names ("height_cm", "weight_kg", "sex", ...)
//   label_units              JSON text: list of L_s units
//   label_statistics         L_s by 4: mean, standard deviation, min, max over the subjects
//   subject_ids              JSON text: list of N_s subject ids (rows of shape_coefficients)
//   shape_label_offsets      L_s, eq. 10 offsets o
//   shape_label_gradients    K_s by L_s, eq. 10 gradients s (the morph directions)
//   shape_semantic_basis     K_s by K_s, §4.1 basis (first shape_semantic_labels columns are the
//                            Gram–Schmidt'ed semantic directions, the rest the remainder PCA)
//   shape_semantic_variances K_s;  shape_semantic_labels  JSON text list
//   full_mean, full_basis, full_eigenvalues, full_coefficients, full_labels, full_label_names,
//   full_label_units, full_label_statistics, full_sample_ids (scan ids), full_label_offsets,
//   full_label_gradients, full_semantic_basis, full_semantic_variances, full_semantic_labels
//                            the same for the full model (all scans; labels include the joint
//                            angles "pose:<bone>:rx|ry|rz", radians, rotation-vector components)
//   full_basis_is_shape_basis scalar 1 in place of full_basis when the two are equal (one person
//                            in many poses; one standard-pose mesh per person): stored once
//   rig_bone_names (JSON text), rig_parents (#B int), rig_head_regressor, rig_tail_regressor,
//   rig_weights             optional skeleton; sparse matrices as (row, col, value) triplets,
//                            #nonzeros by 3, with rig_*_shape = [rows, cols]
//
// Reading it from Python:
//   import numpy as np, json
//   m = np.load("model.npz")
//   names = json.loads(str(m["label_names"]))
//   h = names.index("height_cm")
//   c = m["shape_coefficients"][0]                       # first subject
//   print(m["shape_label_offsets"][h] + c @ m["shape_label_gradients"][:, h])  # predicted cm
//   x = m["shape_mean"] + m["shape_basis"] @ c           # its encoding (relative to encoding_mean)
#pragma once

#include <filesystem>

#include "core/io/npz.h"
#include "model/body_model.h"

namespace bodymodel {

Npz model_to_npz(const BodyModel& model);
// Throws InputError naming the file when a key is missing, the format or version is not this
// one, or the arrays' shapes disagree.
BodyModel model_from_npz(const Npz& npz, const std::string& what = "model");

void save_model(const std::filesystem::path& path, const BodyModel& model);
BodyModel load_model(const std::filesystem::path& path);

}  // namespace bodymodel
