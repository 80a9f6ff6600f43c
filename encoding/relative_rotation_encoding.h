// Relative rotation encoding (RRE) of meshes that share a template's topology: Hasler et al.
// 2009 §3, docs/method.md §3.2. This is the model's coordinate system: morphing, PCA, regression,
// interpolation and pose changes are linear operations on these vectors, and
// RelativeRotationDecoder (encoding/relative_rotation_decoder.h) turns them back into meshes.
//
// Per triangle f the deformation gradient U_f from the template's rest triangle is split by
// polar decomposition into U_f = R_f S_f. For each of the (up to) three edge-adjacent triangles
// g = TT(f, k) the relative rotation R_fg = R_fᵀ R_g is stored as a rotation vector, plus the
// six upper entries of S_f: 15 numbers per triangle.
//
// NOTE on the convention: the paper writes R_ij = R_i · R_j⁻¹ and decodes with R_ij R_j = R_i.
// With R_i the rotation of the polar decomposition (rest → deformed) that product is NOT
// invariant to a global rotation P of the mesh (it becomes P R_i R_jᵀ Pᵀ), and a decode with one
// triangle fixed then yields R_i Q instead of P R_i, i.e. a wrong shape. We store R_fᵀ R_g, which
// is the paper's R_i R_j⁻¹ for the inverse rotations T_i = R_iᵀ (deformed → rest): invariant,
// and the decoder solves the paper's system R_fg T_g − T_f = 0 for T and transposes.
//
// LAYOUT of an encoding vector (size 15·#F, triangle-major, doubles):
//   values[15 f + 3 k + c], k = 0..2, c = 0..2   rotation vector (radians) of R_{f, TT(f,k)}, where
//                                                 TT(f, k) is the triangle across edge k of f
//                                                 (edge k = F(f,k) → F(f,(k+1)%3), see
//                                                 core/geometry.h triangle_adjacency)
//   values[15 f + 9 + m], m = 0..5               S_f entries xx, xy, xz, yy, yz, zz
// BOUNDARY triangles (open meshes) have fewer than three neighbours: the slot of a missing
// neighbour (TT(f,k) = −1) is stored as 0, carries no equation in the decoder, and is ignored
// by every operation (its value never matters). Closed manifolds use all 15 numbers.
//
// MEAN-RELATIVE storage (paper §3, last paragraph): an Encoding is relative to an EncodingMean,
// the component-wise average of the absolute encodings of a set of meshes. Stretch entries are
// stored as differences S − S̄; a relative rotation as the rotation vector δ with
// R_fg = R̄_fg · exp(δ), R̄_fg = exp(mean rotation vector), so the mean encodes to exactly 0 and
// rotation vectors stay small near the mean. A null mean means "relative to the template"
// (R̄ = I, S̄ = I): then `values` are the absolute numbers.
//
// Linear operations (+, −, scalar ·, interpolate, masked_change) act on `values` and require
// operands relative to the same mean.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

namespace bodymodel {

inline constexpr int kEncodingValuesPerTriangle = 15;

// The template: rest shape, topology and everything that depends only on them.
class EncodingTemplate {
 public:
  // V_rest #V by 3 (mm for bodies), F #F by 3. Throws InputError for out-of-range indices, a
  // repeated vertex in a face, a non-manifold edge (an edge of > 2 triangles), non-finite
  // coordinates or a zero-area rest triangle, naming the element.
  EncodingTemplate(Eigen::MatrixX3d V_rest, Eigen::MatrixX3i F);

  const Eigen::MatrixX3d& rest_vertices() const { return V_rest_; }   // #V by 3
  const Eigen::MatrixX3i& faces() const { return F_; }                // #F by 3
  const Eigen::MatrixX3i& adjacency() const { return TT_; }           // #F by 3, −1 = boundary
  const std::vector<Eigen::Matrix3d>& inverse_rest_frames() const { return W_rest_inv_; }
  int vertex_count() const { return static_cast<int>(V_rest_.rows()); }
  int triangle_count() const { return static_cast<int>(F_.rows()); }
  int encoding_size() const { return kEncodingValuesPerTriangle * triangle_count(); }
  int boundary_slot_count() const { return boundary_slots_; }

  // Throws InputError (naming `what`) unless V is #V by 3 with finite coordinates.
  void check_vertices(const Eigen::MatrixX3d& V, const std::string& what) const;
  // Throws InputError (naming `what`) unless F equals the template's faces.
  void check_faces(const Eigen::MatrixX3i& F, const std::string& what) const;

 private:
  Eigen::MatrixX3d V_rest_;
  Eigen::MatrixX3i F_, TT_;
  std::vector<Eigen::Matrix3d> W_rest_inv_;
  int boundary_slots_ = 0;
};

// The mean an encoding is relative to.
struct EncodingMean {
  Eigen::VectorXd values;                      // 15·#F absolute component-wise mean
  std::vector<Eigen::Matrix3d> slot_rotations; // 3·#F: exp of the mean rotation vectors

  // Builds the mean from its absolute values (fills slot_rotations).
  static std::shared_ptr<const EncodingMean> from_values(Eigen::VectorXd values);
  // Component-wise average of absolute encodings (each 15·#F); InputError if empty or the
  // sizes differ.
  static std::shared_ptr<const EncodingMean> average(const std::vector<Eigen::VectorXd>& absolute);
};

// An encoded mesh relative to `mean` (null = relative to the template itself).
struct Encoding {
  Eigen::VectorXd values;                      // 15·#F, layout above
  std::shared_ptr<const EncodingMean> mean;

  int triangle_count() const { return static_cast<int>(values.size() / kEncodingValuesPerTriangle); }
};

// Absolute encoding of V (#V by 3, the template's vertex order and faces). Zero-area triangles
// in V are encoded robustly (their rotation is one valid choice, see polar_decomposition), so
// the round trip still holds. Throws InputError for a wrong vertex count or NaN coordinates.
Eigen::VectorXd encode_absolute(const EncodingTemplate& tmpl, const Eigen::MatrixX3d& V);

// Relative encoding of V with respect to `mean` (null: the template).
Encoding encode(const EncodingTemplate& tmpl, const Eigen::MatrixX3d& V,
                std::shared_ptr<const EncodingMean> mean = nullptr);

// Re-expresses absolute values relative to `mean`, and back.
Encoding relative_to(std::shared_ptr<const EncodingMean> mean, const Eigen::VectorXd& absolute);
Eigen::VectorXd absolute_values(const Encoding& e);
// The same encoding relative to another mean (exact for the stretch part, and for rotations).
Encoding rebase(const Encoding& e, std::shared_ptr<const EncodingMean> mean);

// Encodes a set of meshes relative to their own component-wise mean (paper §3).
struct EncodedSet {
  std::shared_ptr<const EncodingMean> mean;
  std::vector<Encoding> encodings;
};
EncodedSet encode_set(const EncodingTemplate& tmpl, const std::vector<Eigen::MatrixX3d>& meshes);

// Per slot (3·#F) the relative rotation R_{f, TT(f,k)} and per triangle the stretch S_f that
// an encoding stands for (R_fg = R_fᵀ R_g; unset for boundary slots). Used by the decoder.
void encoding_matrices(const Encoding& e, std::vector<Eigen::Matrix3d>& slot_rotations,
                       std::vector<Eigen::Matrix3d>& stretches);

// ---- linear operations (same mean required; InputError otherwise) ----------------------------
Encoding operator+(const Encoding& a, const Encoding& b);
Encoding operator-(const Encoding& a, const Encoding& b);
Encoding operator*(double s, const Encoding& a);
// (1 − t)·a + t·b.
Encoding interpolate(const Encoding& a, const Encoding& b, double t);
// Selective change (paper §5.1, Fig. 6): base + m_f · (changed − base) on the 15 numbers of
// each triangle f. triangle_mask #F, usually in [0, 1] (1 = take the change, 0 = keep base).
Encoding masked_change(const Encoding& base, const Encoding& changed,
                       const Eigen::VectorXd& triangle_mask);
// Triangle mask from a vertex mask (#V): the mean of its three vertices' values.
Eigen::VectorXd triangle_mask_from_vertices(const Eigen::MatrixX3i& F,
                                            const Eigen::VectorXd& vertex_mask);

}  // namespace bodymodel
