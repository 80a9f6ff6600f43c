#include "skinning/bone_recovery.h"

#include <chrono>
#include <cmath>
#include <random>
#include <sstream>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/geometry.h"
#include "skinning/skinning_examples.h"

namespace bodymodel {
namespace {

Eigen::Matrix3d nearest_rotation(const Eigen::Matrix3d& A) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU();
  const Eigen::Matrix3d V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0) U.col(2) *= -1;
  return U * V.transpose();
}

// Sumner's frame of a triangle: two edges and the scaled normal.
Eigen::Matrix3d triangle_frame(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, Eigen::Index f) {
  const Eigen::Vector3d a = V.row(F(f, 0)), b = V.row(F(f, 1)), c = V.row(F(f, 2));
  const Eigen::Vector3d e1 = b - a, e2 = c - a;
  Eigen::Vector3d nrm = e1.cross(e2);
  const double len = nrm.norm();
  nrm = len > 0 ? Eigen::Vector3d(nrm / std::sqrt(len)) : Eigen::Vector3d::Zero();
  Eigen::Matrix3d D;
  D << e1, e2, nrm;
  return D;
}

// Weighted Kabsch: rigid map with Σ w ‖R a + t − b‖² minimal.
Eigen::Affine3d weighted_kabsch(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                                const std::vector<double>& w) {
  double sw = 0;
  Eigen::Vector3d ca = Eigen::Vector3d::Zero(), cb = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < a.size(); ++i) sw += w[i], ca += w[i] * a[i], cb += w[i] * b[i];
  Eigen::Affine3d T = Eigen::Affine3d::Identity();
  if (sw <= 0) return T;
  ca /= sw;
  cb /= sw;
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < a.size(); ++i) S += w[i] * (b[i] - cb) * (a[i] - ca).transpose();
  T.linear() = nearest_rotation(S);
  T.translation() = cb - T.linear() * ca;
  return T;
}

}  // namespace

std::string BoneRecoverySummary::brief() const {
  std::ostringstream s;
  s << "bone recovery: " << bones << " bones over " << frames << " frames, k-means "
    << kmeans_iterations << " iterations; rigid residual RMS " << rms_rigid_residual << "; "
    << seconds << " s";
  return s.str();
}

BoneTransforms fit_section_transforms(const Eigen::MatrixX3d& rest, const Eigen::VectorXi& vertex_bone,
                                      int bones, const Eigen::MatrixX3d& Q) {
  if (Q.rows() != rest.rows())
    throw InputError("bone transforms: the frame has " + std::to_string(Q.rows()) +
                     " vertices, the rest mesh " + std::to_string(rest.rows()));
  std::vector<std::vector<Eigen::Vector3d>> A(static_cast<size_t>(bones)), Bv(static_cast<size_t>(bones));
  for (Eigen::Index i = 0; i < rest.rows(); ++i) {
    A[static_cast<size_t>(vertex_bone(i))].push_back(rest.row(i).transpose());
    Bv[static_cast<size_t>(vertex_bone(i))].push_back(Q.row(i).transpose());
  }
  BoneTransforms T(static_cast<size_t>(bones), Eigen::Affine3d::Identity());
  for (int b = 0; b < bones; ++b) {
    const auto& a = A[static_cast<size_t>(b)];
    if (a.size() < 3) continue;
    T[static_cast<size_t>(b)] = weighted_kabsch(a, Bv[static_cast<size_t>(b)], std::vector<double>(a.size(), 1.0));
  }
  return T;
}

namespace {

// The inputs bone recovery needs: a positive bone count no larger than the triangle count, frames
// of the rest mesh's size, finite coordinates and face indices in range.
void check_recovery_input(const Eigen::MatrixX3d& rest, const Eigen::MatrixX3i& F,
                          const std::vector<Eigen::MatrixX3d>& frames, int Bn) {
  const Eigen::Index n = rest.rows(), nf = F.rows();
  const int P = static_cast<int>(frames.size());
  if (Bn < 1) throw InputError("bone recovery: the bone count must be at least 1, found " + std::to_string(Bn));
  if (Bn > nf)
    throw InputError("bone recovery: " + std::to_string(Bn) + " bones requested but the mesh has only " +
                     std::to_string(nf) + " triangles");
  if (P < 1) throw InputError("bone recovery: no frames");
  if (!rest.allFinite()) throw InputError("bone recovery: the rest mesh contains NaN");
  // Only indices matter here (non-manifold meshes such as Sumner's camel are fine).
  if (F.size() && (F.minCoeff() < 0 || F.maxCoeff() >= n))
    throw InputError("bone recovery: a face index is outside 0.." + std::to_string(n - 1));
  for (int p = 0; p < P; ++p) {
    if (frames[static_cast<size_t>(p)].rows() != n)
      throw InputError("bone recovery: frame " + std::to_string(p) + " has " +
                       std::to_string(frames[static_cast<size_t>(p)].rows()) + " vertices, the rest mesh has " +
                       std::to_string(n));
    if (!frames[static_cast<size_t>(p)].allFinite())
      throw InputError("bone recovery: frame " + std::to_string(p) + " contains NaN");
  }
}

// k-means++ seeding of Bn centres among the rows of X (draws from rng in a fixed order).
Eigen::MatrixXd kmeans_plus_plus(const Eigen::MatrixXd& X, int Bn, std::mt19937& rng) {
  const Eigen::Index nf = X.rows();
  Eigen::MatrixXd centers(Bn, X.cols());
  Eigen::VectorXd d2 = Eigen::VectorXd::Constant(nf, std::numeric_limits<double>::infinity());
  centers.row(0) = X.row(std::uniform_int_distribution<Eigen::Index>(0, nf - 1)(rng));
  for (int c = 1; c < Bn; ++c) {
    for (Eigen::Index f = 0; f < nf; ++f) d2(f) = std::min(d2(f), (X.row(f) - centers.row(c - 1)).squaredNorm());
    const double total = d2.sum();
    Eigen::Index pick = 0;
    if (total > 0) {
      double u = std::uniform_real_distribution<double>(0, total)(rng), acc = 0;
      for (pick = 0; pick < nf - 1; ++pick) {
        acc += d2(pick);
        if (acc >= u) break;
      }
    } else {
      pick = std::uniform_int_distribution<Eigen::Index>(0, nf - 1)(rng);
    }
    centers.row(c) = X.row(pick);
  }
  return centers;
}

}  // namespace

RecoveredBones recover_bones(const Eigen::MatrixX3d& rest, const Eigen::MatrixX3i& F,
                             const std::vector<Eigen::MatrixX3d>& frames,
                             const BoneRecoveryOptions& options, BoneRecoverySummary* summary,
                             const ProgressCallback& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  const Eigen::Index n = rest.rows(), nf = F.rows();
  const int P = static_cast<int>(frames.size()), Bn = options.bones;
  check_recovery_input(rest, F, frames, Bn);
  // Rotation sequences: 9·P features per triangle.
  report_progress(progress, 0.0, "triangle rotations");
  Eigen::MatrixXd X(nf, 9 * P);
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, nf, 256), [&](const auto& r) {
    for (Eigen::Index f = r.begin(); f < r.end(); ++f) {
      const Eigen::Matrix3d D0 = triangle_frame(rest, F, f);
      const double det = D0.determinant();
      const Eigen::Matrix3d D0inv = std::abs(det) > 1e-300 ? Eigen::Matrix3d(D0.inverse()) : Eigen::Matrix3d::Identity();
      for (int p = 0; p < P; ++p) {
        const Eigen::Matrix3d R = nearest_rotation(triangle_frame(frames[static_cast<size_t>(p)], F, f) * D0inv);
        X.row(f).segment<9>(9 * p) = Eigen::Map<const Eigen::Matrix<double, 1, 9>>(R.data());
      }
    }
  });
  // k-means++ seeding.
  std::mt19937 rng(options.seed);
  Eigen::MatrixXd centers = kmeans_plus_plus(X, Bn, rng);
  Eigen::VectorXi label = Eigen::VectorXi::Constant(nf, -1);
  int it = 0;
  for (; it < options.kmeans_iterations; ++it) {
    report_progress(progress, 0.1 + 0.5 * it / std::max(1, options.kmeans_iterations), "clustering rotations");
    std::atomic<int> changed{0};
    // ‖x − c‖² = ‖x‖² − 2 x·c + ‖c‖², and ‖x‖² is the same for every centre: the assignment is one
    // matrix product per block of triangles (it was 46 % of a Vlasic jumping fit done row by row).
    const Eigen::RowVectorXd cn = centers.rowwise().squaredNorm().transpose();
    tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, nf, 512), [&](const auto& r) {
      int ch = 0;
      const Eigen::Index m = r.end() - r.begin();
      Eigen::MatrixXd G(m, Bn);
      G.noalias() = X.middleRows(r.begin(), m) * centers.transpose();
      for (Eigen::Index k = 0; k < m; ++k) {
        Eigen::Index best;
        (cn - 2.0 * G.row(k)).minCoeff(&best);
        const Eigen::Index f = r.begin() + k;
        if (label(f) != best) ++ch, label(f) = static_cast<int>(best);
      }
      changed += ch;
    });
    Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(Bn, 9 * P);
    Eigen::VectorXd count = Eigen::VectorXd::Zero(Bn);
    for (Eigen::Index f = 0; f < nf; ++f) sum.row(label(f)) += X.row(f), count(label(f)) += 1;
    for (int c = 0; c < Bn; ++c) {
      if (count(c) > 0) {
        centers.row(c) = sum.row(c) / count(c);
      } else {   // empty cluster: re-seed at the triangle farthest from its centre
        Eigen::Index far = 0;
        double best = -1;
        for (Eigen::Index f = 0; f < nf; ++f) {
          const double d = (X.row(f) - centers.row(label(f))).squaredNorm();
          if (d > best) best = d, far = f;
        }
        centers.row(c) = X.row(far);
        label(far) = c;
      }
    }
    if (changed.load() == 0) break;
  }
  RecoveredBones out;
  out.triangle_bone = label;
  // Vertex label: the cluster with the largest incident area.
  const Eigen::VectorXd area = face_areas(rest, F);
  Eigen::MatrixXd vote = Eigen::MatrixXd::Zero(n, Bn);
  for (Eigen::Index f = 0; f < nf; ++f)
    for (int c = 0; c < 3; ++c) vote(F(f, c), label(f)) += area(f) + 1e-30;
  out.vertex_bone.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    Eigen::Index best;
    vote.row(i).maxCoeff(&best);
    out.vertex_bone(i) = static_cast<int>(best);
  }
  auto fit_all = [&] {
    out.transforms.assign(static_cast<size_t>(P), {});
    tbb::parallel_for(0, P, [&](int p) {
      out.transforms[static_cast<size_t>(p)] =
          fit_section_transforms(rest, out.vertex_bone, Bn, frames[static_cast<size_t>(p)]);
    });
  };
  fit_all();
  for (int round = 0; round < options.refinement_rounds; ++round) {
    report_progress(progress, 0.6 + 0.4 * round / std::max(1, options.refinement_rounds), "refining sections");
    tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, n, 256), [&](const auto& r) {
      for (Eigen::Index i = r.begin(); i < r.end(); ++i) {
        const Eigen::Vector3d v = rest.row(i).transpose();
        double best = std::numeric_limits<double>::infinity();
        int bb = out.vertex_bone(i);
        for (int b = 0; b < Bn; ++b) {
          double e = 0;
          for (int p = 0; p < P && e < best; ++p)
            e += (out.transforms[static_cast<size_t>(p)][static_cast<size_t>(b)] * v -
                  frames[static_cast<size_t>(p)].row(i).transpose()).squaredNorm();
          if (e < best) best = e, bb = b;
        }
        out.vertex_bone(i) = bb;
      }
    });
    fit_all();
  }
  report_progress(progress, 1.0, "bones recovered");
  if (summary) {
    summary->bones = Bn;
    summary->frames = P;
    summary->kmeans_iterations = it;
    double s = 0;
    for (int p = 0; p < P; ++p)
      for (Eigen::Index i = 0; i < n; ++i)
        s += (out.transforms[static_cast<size_t>(p)][static_cast<size_t>(out.vertex_bone(i))] * Eigen::Vector3d(rest.row(i).transpose()) -
              frames[static_cast<size_t>(p)].row(i).transpose()).squaredNorm();
    summary->rms_rigid_residual = std::sqrt(s / (double(P) * n));
    summary->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  return out;
}

namespace {
void check_fixed_weight_fit(const SkinningRig& rig, const Eigen::MatrixX3d& Q, const BoneTransforms& initial) {
  if (rig.method != SkinningMethod::lbs)
    throw InputError("fixed-weight transform fit: expected an ssd rig, found " + skinning_method_name(rig.method));
  if (Q.rows() != rig.rest.rows())
    throw InputError("fixed-weight transform fit: the frame has " + std::to_string(Q.rows()) +
                     " vertices, the rig " + std::to_string(rig.rest.rows()));
  if (!Q.allFinite()) throw InputError("fixed-weight transform fit: the frame contains NaN");
  if (static_cast<int>(initial.size()) != rig.bone_count)
    throw InputError("fixed-weight transform fit: " + std::to_string(initial.size()) +
                     " initial transforms for " + std::to_string(rig.bone_count) + " bones");
  std::string problem;
  if (!transforms_are_rigid({initial}, 1e-4, &problem))
    throw InputError("fixed-weight transform fit: rigid initial transforms are required but " + problem);
}

// Member threshold of a bone's Procrustes problem (a weight this small moves nothing).
constexpr double kMemberWeight = 1e-8;
}  // namespace

FixedWeightMoments fixed_weight_moments(const SkinningRig& rig) {
  const Eigen::Index n = rig.rest.rows(), K = rig.influences.cols();
  const int B = rig.bone_count;
  FixedWeightMoments m;
  m.bones = B;
  m.members.assign(static_cast<size_t>(B), 0);
  m.self.assign(static_cast<size_t>(B), Eigen::Matrix4d::Zero());
  // Dense B × B slots while accumulating, then the non-empty ones per bone.
  std::vector<int> slot(static_cast<size_t>(B) * B, -1);
  std::vector<Eigen::Matrix4d> acc;
  std::vector<std::pair<int, int>> which;
  for (Eigen::Index i = 0; i < n; ++i) {
    Eigen::Vector4d v;
    v << rig.rest.row(i).transpose(), 1.0;
    const Eigen::Matrix4d vv = v * v.transpose();
    for (Eigen::Index a = 0; a < K; ++a) {
      const int b = rig.influences(i, a);
      const double wa = rig.coefficients(i, a);
      if (b < 0 || !(wa > kMemberWeight)) continue;
      ++m.members[static_cast<size_t>(b)];
      m.self[static_cast<size_t>(b)] += (wa * wa) * vv;
      for (Eigen::Index c = 0; c < K; ++c) {
        const int k = rig.influences(i, c);
        if (k < 0) continue;
        int& s = slot[static_cast<size_t>(b) * B + static_cast<size_t>(k)];
        if (s < 0) {
          s = static_cast<int>(acc.size());
          acc.push_back(Eigen::Matrix4d::Zero());
          which.push_back({b, k});
        }
        acc[static_cast<size_t>(s)] += (wa * rig.coefficients(i, c)) * vv;
      }
    }
  }
  m.cross.assign(static_cast<size_t>(B), {});
  for (size_t s = 0; s < acc.size(); ++s) m.cross[static_cast<size_t>(which[s].first)].push_back({which[s].second, acc[s]});
  return m;
}

BoneTransforms fit_transforms_with_fixed_weights(const SkinningRig& rig, const Eigen::MatrixX3d& Q,
                                                 const BoneTransforms& initial, int iterations,
                                                 const FixedWeightMoments* moments) {
  check_fixed_weight_fit(rig, Q, initial);
  FixedWeightMoments own;
  if (!moments || moments->bones != rig.bone_count) {
    own = fixed_weight_moments(rig);
    moments = &own;
  }
  const Eigen::Index n = rig.rest.rows(), K = rig.influences.cols();
  const int B = rig.bone_count;
  // The frame's side of the sums: Σ_i w_ib q_i ṽ_iᵀ per bone (3 × 4).
  std::vector<Eigen::Matrix<double, 3, 4>> q(static_cast<size_t>(B), Eigen::Matrix<double, 3, 4>::Zero());
  for (Eigen::Index i = 0; i < n; ++i) {
    Eigen::Vector4d v;
    v << rig.rest.row(i).transpose(), 1.0;
    const Eigen::Vector3d qi = Q.row(i).transpose();
    const Eigen::Matrix<double, 3, 4> qv = qi * v.transpose();
    for (Eigen::Index a = 0; a < K; ++a) {
      const int b = rig.influences(i, a);
      const double wa = rig.coefficients(i, a);
      if (b >= 0 && wa > kMemberWeight) q[static_cast<size_t>(b)] += wa * qv;
    }
  }
  BoneTransforms T = initial;
  for (int it = 0; it < iterations; ++it) {
    for (int b = 0; b < B; ++b) {
      if (moments->members[static_cast<size_t>(b)] < 3) continue;
      // Σ_i w_ib (q_i − Σ_k w_ik T_k ṽ_i + w_ib T_b ṽ_i) ṽ_iᵀ = [Σ w r vᵀ | Σ w r] of the per-vertex form.
      const Eigen::Matrix4d& D = moments->self[static_cast<size_t>(b)];
      Eigen::Matrix<double, 3, 4> sum = q[static_cast<size_t>(b)] + T[static_cast<size_t>(b)].matrix().topRows<3>() * D;
      for (const auto& [k, M] : moments->cross[static_cast<size_t>(b)])
        sum.noalias() -= T[static_cast<size_t>(k)].matrix().topRows<3>() * M;
      const double sw = D(3, 3);
      if (sw <= 0) continue;
      const Eigen::Vector3d ca = D.block<3, 1>(0, 3) / sw, cb = sum.col(3) / sw;
      const Eigen::Matrix3d S = sum.leftCols<3>() - sw * cb * ca.transpose();
      Eigen::Affine3d Tn = Eigen::Affine3d::Identity();
      Tn.linear() = nearest_rotation(S);
      Tn.translation() = cb - Tn.linear() * ca;
      T[static_cast<size_t>(b)] = Tn;
    }
  }
  return T;
}

BoneTransforms fit_transforms_with_fixed_weights_per_vertex(const SkinningRig& rig, const Eigen::MatrixX3d& Q,
                                                            const BoneTransforms& initial, int iterations) {
  check_fixed_weight_fit(rig, Q, initial);
  const Eigen::Index n = rig.rest.rows(), K = rig.influences.cols();
  const int B = rig.bone_count;
  // Vertices influenced by each bone, with the weight.
  std::vector<std::vector<std::pair<int, double>>> members(static_cast<size_t>(B));
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index k = 0; k < K; ++k)
      if (rig.influences(i, k) >= 0 && rig.coefficients(i, k) > 1e-8)
        members[static_cast<size_t>(rig.influences(i, k))].push_back({static_cast<int>(i), rig.coefficients(i, k)});
  BoneTransforms T = initial;
  // Rows of `current` (#V by 3, Σ_k w_k M_k v) and of Q as contiguous 3-vectors.
  Eigen::Matrix3Xd current = evaluate_rig(rig, T).transpose();
  const Eigen::Matrix3Xd Qt = Q.transpose(), Vt = rig.rest.transpose();
  for (int it = 0; it < iterations; ++it) {
    for (int b = 0; b < B; ++b) {
      const auto& mem = members[static_cast<size_t>(b)];
      if (mem.size() < 3) continue;
      // Weighted Procrustes on the residual of the other bones, in one pass over the members:
      // ‖wi (R v + t) − (q − others)‖² = wi² ‖R v + t − (q − others)/wi‖², so with weights wi²
      // and targets (q − others)/wi: Σ wi², Σ wi² v, Σ wi (q − others), Σ wi (q − others) vᵀ.
      const Eigen::Affine3d& Tb = T[static_cast<size_t>(b)];
      double sw = 0;
      Eigen::Vector3d sa = Eigen::Vector3d::Zero(), sb = Eigen::Vector3d::Zero();
      Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
      for (const auto& [i, wi] : mem) {
        const Eigen::Vector3d v = Vt.col(i);
        const Eigen::Vector3d r = Qt.col(i) - current.col(i) + wi * (Tb * v);   // wi · target
        sw += wi * wi;
        sa += wi * wi * v;
        sb += wi * r;
        S.noalias() += wi * r * v.transpose();
      }
      if (sw <= 0) continue;
      const Eigen::Vector3d ca = sa / sw, cb = sb / sw;
      S -= sw * cb * ca.transpose();
      Eigen::Affine3d Tn = Eigen::Affine3d::Identity();
      Tn.linear() = nearest_rotation(S);
      Tn.translation() = cb - Tn.linear() * ca;
      const Eigen::Matrix3d dR = Tn.linear() - Tb.linear();
      const Eigen::Vector3d dt = Tn.translation() - Tb.translation();
      for (const auto& [i, wi] : mem) current.col(i) += wi * (dR * Vt.col(i) + dt);
      T[static_cast<size_t>(b)] = Tn;
    }
  }
  return T;
}

}  // namespace bodymodel
