#include "encoding/relative_rotation_encoding.h"

#include <tbb/parallel_for.h>

#include <Eigen/Geometry>

#include <string>

#include "core/error.h"
#include "core/geometry.h"
#include "encoding/deformation_gradient.h"

namespace bodymodel {

namespace {

constexpr int kStride = kEncodingValuesPerTriangle;
constexpr int kGrain = 1024;

template <typename Fn>
void for_each_triangle(int n, Fn&& fn) {
  tbb::parallel_for(tbb::blocked_range<int>(0, n, kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int f = r.begin(); f < r.end(); ++f) fn(f);
  });
}

void put_stretch(const Eigen::Matrix3d& S, double* out) {
  out[0] = S(0, 0), out[1] = S(0, 1), out[2] = S(0, 2);
  out[3] = S(1, 1), out[4] = S(1, 2), out[5] = S(2, 2);
}

Eigen::Matrix3d get_stretch(const double* s) {
  Eigen::Matrix3d S;
  S << s[0], s[1], s[2], s[1], s[3], s[4], s[2], s[4], s[5];
  return S;
}

void check_same_mean(const Encoding& a, const Encoding& b, const char* op) {
  if (a.values.size() != b.values.size())
    throw InputError(std::string("encoding ") + op + ": expected encodings of the same size, found " +
                     std::to_string(a.values.size()) + " and " + std::to_string(b.values.size()));
  if (a.mean != b.mean && !(a.mean && b.mean && a.mean->values == b.mean->values))
    throw InputError(std::string("encoding ") + op +
                     ": expected encodings relative to the same mean, found different means "
                     "(use rebase() first)");
}

}  // namespace

// ---- template -------------------------------------------------------------------------------

EncodingTemplate::EncodingTemplate(Eigen::MatrixX3d V_rest, Eigen::MatrixX3i F)
    : V_rest_(std::move(V_rest)), F_(std::move(F)) {
  if (F_.rows() == 0) throw InputError("template: expected at least one triangle, found none");
  check_triangle_mesh(V_rest_, F_, "template");
  TT_ = triangle_adjacency(F_);
  boundary_slots_ = static_cast<int>((TT_.array() < 0).count());
  W_rest_inv_ = bodymodel::inverse_rest_frames(V_rest_, F_);
}

void EncodingTemplate::check_vertices(const Eigen::MatrixX3d& V, const std::string& what) const {
  if (V.rows() != V_rest_.rows())
    throw InputError(what + ": expected " + std::to_string(V_rest_.rows()) +
                     " vertices (the template's), found " + std::to_string(V.rows()));
  if (!V.allFinite())
    for (Eigen::Index i = 0; i < V.rows(); ++i)
      if (!V.row(i).allFinite())
        throw InputError(what + ": vertex " + std::to_string(i) +
                         " has a NaN or infinite coordinate");
}

void EncodingTemplate::check_faces(const Eigen::MatrixX3i& F, const std::string& what) const {
  if (F.rows() != F_.rows())
    throw InputError(what + ": expected " + std::to_string(F_.rows()) +
                     " triangles (the template's), found " + std::to_string(F.rows()));
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    if (F.row(f) != F_.row(f))
      throw InputError(what + ": triangle " + std::to_string(f) + " is (" +
                       std::to_string(F(f, 0)) + ", " + std::to_string(F(f, 1)) + ", " +
                       std::to_string(F(f, 2)) + "), expected the template's (" +
                       std::to_string(F_(f, 0)) + ", " + std::to_string(F_(f, 1)) + ", " +
                       std::to_string(F_(f, 2)) + ")");
}

// ---- mean -----------------------------------------------------------------------------------

std::shared_ptr<const EncodingMean> EncodingMean::from_values(Eigen::VectorXd values) {
  if (values.size() % kStride != 0)
    throw InputError("encoding mean: expected a multiple of 15 values, found " +
                     std::to_string(values.size()));
  if (!values.allFinite()) throw InputError("encoding mean: expected finite values, found NaN");
  auto m = std::make_shared<EncodingMean>();
  m->values = std::move(values);
  const int nf = static_cast<int>(m->values.size() / kStride);
  m->slot_rotations.resize(3 * static_cast<size_t>(nf));
  for_each_triangle(nf, [&](int f) {
    for (int k = 0; k < 3; ++k)
      m->slot_rotations[3 * f + k] =
          rotation_exp(m->values.segment<3>(static_cast<Eigen::Index>(kStride) * f + 3 * k));
  });
  return m;
}

std::shared_ptr<const EncodingMean> EncodingMean::average(
    const std::vector<Eigen::VectorXd>& absolute) {
  if (absolute.empty()) throw InputError("encoding mean: expected at least one encoding, found none");
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(absolute[0].size());
  for (size_t i = 0; i < absolute.size(); ++i) {
    if (absolute[i].size() != sum.size())
      throw InputError("encoding mean: encoding " + std::to_string(i) + " has " +
                       std::to_string(absolute[i].size()) + " values, expected " +
                       std::to_string(sum.size()));
    sum += absolute[i];
  }
  return from_values(sum / static_cast<double>(absolute.size()));
}

// ---- encoding -------------------------------------------------------------------------------

namespace {

// Encoding of V relative to `mean` (null: absolute), straight from the rotations.
Eigen::VectorXd encode_values(const EncodingTemplate& tmpl, const Eigen::MatrixX3d& V,
                              const EncodingMean* mean) {
  tmpl.check_vertices(V, "mesh to encode");
  const int nf = tmpl.triangle_count();
  const Eigen::MatrixX3i& F = tmpl.faces();
  const Eigen::MatrixX3i& TT = tmpl.adjacency();
  const auto& Winv = tmpl.inverse_rest_frames();
  std::vector<Eigen::Matrix3d> R(nf);
  Eigen::VectorXd x(static_cast<Eigen::Index>(kStride) * nf);
  for_each_triangle(nf, [&](int f) {
    const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
    Eigen::Matrix3d W;
    const Eigen::Vector3d e1 = b - a, e2 = c - a, n = e1.cross(e2);
    const double len = n.norm();
    W.col(0) = e1;
    W.col(1) = e2;
    W.col(2) = len > 0 ? Eigen::Vector3d(n / std::sqrt(len)) : Eigen::Vector3d::Zero();
    const PolarDecomposition p = polar_decomposition(W * Winv[f]);
    R[f] = p.R;
    put_stretch(p.S, x.data() + static_cast<Eigen::Index>(kStride) * f + 9);
  });
  for_each_triangle(nf, [&](int f) {
    for (int k = 0; k < 3; ++k) {
      const int g = TT(f, k);
      const Eigen::Index o = static_cast<Eigen::Index>(kStride) * f;
      if (g < 0)
        x.segment<3>(o + 3 * k).setZero();
      else if (mean)
        x.segment<3>(o + 3 * k) =
            rotation_log(mean->slot_rotations[3 * f + k].transpose() * R[f].transpose() * R[g]);
      else
        x.segment<3>(o + 3 * k) = rotation_log(R[f].transpose() * R[g]);
    }
    if (mean) x.segment<6>(static_cast<Eigen::Index>(kStride) * f + 9) -=
        mean->values.segment<6>(static_cast<Eigen::Index>(kStride) * f + 9);
  });
  return x;
}

}  // namespace

Eigen::VectorXd encode_absolute(const EncodingTemplate& tmpl, const Eigen::MatrixX3d& V) {
  return encode_values(tmpl, V, nullptr);
}

Encoding relative_to(std::shared_ptr<const EncodingMean> mean, const Eigen::VectorXd& absolute) {
  Encoding e;
  e.mean = std::move(mean);
  if (!e.mean) {
    e.values = absolute;
    return e;
  }
  if (e.mean->values.size() != absolute.size())
    throw InputError("encoding: expected " + std::to_string(e.mean->values.size()) +
                     " values (the mean's), found " + std::to_string(absolute.size()));
  e.values.resize(absolute.size());
  const int nf = static_cast<int>(absolute.size() / kStride);
  const EncodingMean& m = *e.mean;
  for_each_triangle(nf, [&](int f) {
    const Eigen::Index o = static_cast<Eigen::Index>(kStride) * f;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Matrix3d Rfg = rotation_exp(absolute.segment<3>(o + 3 * k));
      e.values.segment<3>(o + 3 * k) = rotation_log(m.slot_rotations[3 * f + k].transpose() * Rfg);
    }
    e.values.segment<6>(o + 9) = absolute.segment<6>(o + 9) - m.values.segment<6>(o + 9);
  });
  return e;
}

Eigen::VectorXd absolute_values(const Encoding& e) {
  if (!e.mean) return e.values;
  const int nf = e.triangle_count();
  Eigen::VectorXd x(e.values.size());
  const EncodingMean& m = *e.mean;
  for_each_triangle(nf, [&](int f) {
    const Eigen::Index o = static_cast<Eigen::Index>(kStride) * f;
    for (int k = 0; k < 3; ++k)
      x.segment<3>(o + 3 * k) =
          rotation_log(m.slot_rotations[3 * f + k] * rotation_exp(e.values.segment<3>(o + 3 * k)));
    x.segment<6>(o + 9) = e.values.segment<6>(o + 9) + m.values.segment<6>(o + 9);
  });
  return x;
}

Encoding rebase(const Encoding& e, std::shared_ptr<const EncodingMean> mean) {
  if (e.mean == mean) return e;
  return relative_to(std::move(mean), absolute_values(e));
}

Encoding encode(const EncodingTemplate& tmpl, const Eigen::MatrixX3d& V,
                std::shared_ptr<const EncodingMean> mean) {
  if (mean && mean->values.size() != tmpl.encoding_size())
    throw InputError("encode: the mean has " + std::to_string(mean->values.size()) +
                     " values, the template needs " + std::to_string(tmpl.encoding_size()));
  Encoding e;
  e.values = encode_values(tmpl, V, mean.get());
  e.mean = std::move(mean);
  return e;
}

EncodedSet encode_set(const EncodingTemplate& tmpl, const std::vector<Eigen::MatrixX3d>& meshes) {
  std::vector<Eigen::VectorXd> absolute;
  absolute.reserve(meshes.size());
  for (const auto& V : meshes) absolute.push_back(encode_absolute(tmpl, V));
  EncodedSet out;
  out.mean = EncodingMean::average(absolute);
  for (const auto& x : absolute) out.encodings.push_back(relative_to(out.mean, x));
  return out;
}

void encoding_matrices(const Encoding& e, std::vector<Eigen::Matrix3d>& slot_rotations,
                       std::vector<Eigen::Matrix3d>& stretches) {
  const int nf = e.triangle_count();
  slot_rotations.resize(3 * static_cast<size_t>(nf));
  stretches.resize(nf);
  const EncodingMean* m = e.mean.get();
  for_each_triangle(nf, [&](int f) {
    const Eigen::Index o = static_cast<Eigen::Index>(kStride) * f;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Matrix3d D = rotation_exp(e.values.segment<3>(o + 3 * k));
      slot_rotations[3 * f + k] = m ? Eigen::Matrix3d(m->slot_rotations[3 * f + k] * D) : D;
    }
    Eigen::Matrix<double, 6, 1> s = e.values.segment<6>(o + 9);
    if (m) s += m->values.segment<6>(o + 9);
    stretches[f] = get_stretch(s.data());
  });
}

// ---- linear operations ------------------------------------------------------------------------

Encoding operator+(const Encoding& a, const Encoding& b) {
  check_same_mean(a, b, "addition");
  return Encoding{a.values + b.values, a.mean};
}

Encoding operator-(const Encoding& a, const Encoding& b) {
  check_same_mean(a, b, "subtraction");
  return Encoding{a.values - b.values, a.mean};
}

Encoding operator*(double s, const Encoding& a) { return Encoding{s * a.values, a.mean}; }

Encoding interpolate(const Encoding& a, const Encoding& b, double t) {
  check_same_mean(a, b, "interpolation");
  return Encoding{(1 - t) * a.values + t * b.values, a.mean};
}

Encoding masked_change(const Encoding& base, const Encoding& changed,
                       const Eigen::VectorXd& triangle_mask) {
  check_same_mean(base, changed, "masked change");
  const int nf = base.triangle_count();
  if (triangle_mask.size() != nf)
    throw InputError("masked change: expected a mask of " + std::to_string(nf) +
                     " triangles, found " + std::to_string(triangle_mask.size()));
  if (!triangle_mask.allFinite()) throw InputError("masked change: the mask has NaN values");
  Encoding out{base.values, base.mean};
  for (int f = 0; f < nf; ++f) {
    const Eigen::Index o = static_cast<Eigen::Index>(kStride) * f;
    out.values.segment<kStride>(o) +=
        triangle_mask(f) * (changed.values.segment<kStride>(o) - base.values.segment<kStride>(o));
  }
  return out;
}

Eigen::VectorXd triangle_mask_from_vertices(const Eigen::MatrixX3i& F,
                                            const Eigen::VectorXd& vertex_mask) {
  Eigen::VectorXd m(F.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k)
      if (F(f, k) < 0 || F(f, k) >= vertex_mask.size())
        throw InputError("triangle mask: triangle " + std::to_string(f) + " refers to vertex " +
                         std::to_string(F(f, k)) + " but the vertex mask has " +
                         std::to_string(vertex_mask.size()) + " entries");
    m(f) = (vertex_mask(F(f, 0)) + vertex_mask(F(f, 1)) + vertex_mask(F(f, 2))) / 3.0;
  }
  return m;
}

}  // namespace bodymodel
