// The model file: a NumPy .npz archive (core/io/npz.h) that `np.load` opens.
//
// FORMAT (format_version 2). Matrices are float64 in C order except shape_basis and full_basis,
// which are float32 (they are nearly the whole file; orthonormal columns with 7 significant
// digits change a decoded body by far less than 0.01 mm). Version 1 files (the same keys, all
// float64) are still read; other versions are refused with an error naming the version.
// Members are deflated (numpy's savez_compressed layout; np.load reads either).
// QUANTISED files (format_version 3, `bodymodel build --quantise 8`, `bodymodel quantise`) hold
// each basis as integer codes instead of `<p>_basis` (model/quantise.h), read back transparently:
//   <p>_basis_column_bits    K int32, 8 or 16: how each column is stored
//   <p>_basis_codes          D by K8 int8: the 8-bit columns, in order (absent when none)
//   <p>_basis_codes16        D by K16 int16: the 16-bit columns, in order (absent when none)
//   <p>_basis_scales         ceil(D / B) by K float32: entry (i, k) = scales[i // B, k] · code(i, k)
//   <p>_basis_block_rows     scalar B (rows sharing one scale within a column)
//   <p>_basis_column_norms   K, the norms of the columns that were quantised (checks the scales)
// PACKED files (format_version 4, per-column widths other than 8 and 16: `bodymodel quantise`'s
// bit allocation, model/quantise.h) hold, in place of _codes / _codes16:
//   <p>_basis_column_bits    K int32, 2 to 16
//   <p>_basis_packed         uint8: column k's D codes q, each stored as q + 2^(b_k−1) − 1 in b_k
//                            bits, least significant bit first; each column starts on a new byte
//                            (Σ_k ceil(D·b_k / 8) bytes; any other length is refused)
// and the same _scales, _block_rows and _column_norms. Files whose columns are all 8 or 16 bits
// are written as version 3, so programs that read version 3 still read them.
// Float32 files stay version 2, so programs that predate quantisation still read them.
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
//   parts_count              optional (`build --parts P`, model/part_pca.h): scalar P; a part-wise
//                            PCA of the full model's training samples, K_p components in all
//   parts_triangle_part      #F int32, the part of each triangle (0..P−1)
//   parts_component_part     K_p int32, the part of each component (components by decreasing variance)
//   parts_coefficients       N_f by K_p, the full model's training samples' coefficients
//   parts_<p>_mean           15·#F_p: part p's rows of full_mean (its triangles in triangle order)
//   parts_<p>_basis          15·#F_p by K_p(p) float32: part p's components restricted to its rows
//                            (zero elsewhere), in the order of parts_component_part; always float32
//   parts_<p>_eigenvalues    K_p(p), their variances
//                            load_model refuses such a file unless asked (PartModelUse::read).
//
// Reading it from Python:
//   import numpy as np, json
//   m = np.load("model.npz")
//   names = json.loads(str(m["label_names"]))
//   h = names.index("height_cm")
//   c = m["shape_coefficients"][0]                       # first subject
//   print(m["shape_label_offsets"][h] + c @ m["shape_label_gradients"][:, h])  # predicted cm
//   x = m["shape_mean"] + m["shape_basis"] @ c           # its encoding (relative to encoding_mean)
//   # a quantised file: codes = D by K from _codes / _codes16 by _column_bits (format 4: column k
//   #   from _packed: np.unpackbits(bytes, bitorder="little")[:D*b].reshape(D, b) @ (1 << np.arange(b))
//   #   − (2**(b−1) − 1), its bytes following the previous columns'), then
//   #   B = np.repeat(m["shape_basis_scales"], int(m["shape_basis_block_rows"]), axis=0)[:D] * codes
#pragma once

#include <filesystem>

#include "core/io/npz.h"
#include "model/body_model.h"

namespace bodymodel {

// How the bases are stored: float32 (basis_bits 32, the default) or quantised to 2 to 16 bits
// in blocks of block_rows rows per scale (model/quantise.h).
struct ModelFileOptions {
  int basis_bits = 32;
  int block_rows = 64;
  // With basis_bits < 32: per-column bits (2 to 16) of each basis (empty: all basis_bits); a
  // shared basis (full = shape) uses shape_column_bits.
  Eigen::VectorXi shape_column_bits, full_column_bits;
  bool omit_bases = false;  // every array but the bases (for estimating a file's size)
  void validate() const;  // InputError naming the bad field
};

Npz model_to_npz(const BodyModel& model, const ModelFileOptions& options = {});
// Throws InputError naming the file when a key is missing, the format or version is not this
// one, or the arrays' shapes disagree.
BodyModel model_from_npz(const Npz& npz, const std::string& what = "model");

void save_model(const std::filesystem::path& path, const BodyModel& model, const ModelFileOptions& options = {});
// Whether load_model reads a file holding a part-wise model (`build --parts`) or refuses it with
// one line: only the verbs that fit the full model (fit, eval-model) and quantise use it.
enum class PartModelUse { refuse, read };
BodyModel load_model(const std::filesystem::path& path, PartModelUse parts = PartModelUse::refuse);

}  // namespace bodymodel
