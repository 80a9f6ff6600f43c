#include "registration/nonrigid.h"

#include <Eigen/CholmodSupport>
#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/fold_repair.h"
#include "core/geometry.h"

namespace bodymodel {

std::vector<double> nonrigid_schedule(const NonrigidOptions& o) {
  std::vector<double> beta;
  if (o.schedule == NonrigidSchedule::paper) {
    const double lambda = std::log(o.k_inf / o.k0) / double(o.t_max);
    for (int t = 0; t < o.t_max; ++t) beta.push_back(o.k0 * std::exp(lambda * t));
  } else {
    const int n = std::max(1, o.fast_steps);
    for (int t = 0; t < n; ++t) {
      const double f = n == 1 ? 1.0 : double(t) / double(n - 1);
      beta.push_back(o.k0 * std::pow(o.fast_k_end / o.k0, f));
    }
  }
  return beta;
}

double median_point_spacing(const PointIndex& index) {
  const int m = index.size();
  if (m < 2) return 0.0;
  const int step = std::max(1, m / 2000);
  std::vector<double> d;
  for (int j = 0; j < m; j += step) {
    std::vector<double> d2;
    index.knn(index.points().row(j).transpose(), 2, &d2);
    if (d2.size() == 2) d.push_back(std::sqrt(d2[1]));
  }
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return d[d.size() / 2];
}

InverseCorrespondences inverse_correspondences(const Eigen::MatrixX3d& V,
                                               const Eigen::MatrixX3d& VN,
                                               const PointCloud& scan,
                                               const PointIndex& scan_index,
                                               const NonrigidOptions& o,
                                               const SegmentLabels* labels) {
  const Eigen::Index n = V.rows(), m = scan.P.rows();
  const bool seg = labels && labels->segments && labels->point_segment.size() == m;
  auto compatible = [&](Eigen::Index j, int i) {
    return !seg || labels->segments->compatible(labels->point_segment(j), labels->segments->vertex_segment(i));
  };
  const double d2max = o.max_distance * o.max_distance;
  const double cos_min = std::cos(o.max_normal_angle_deg * M_PI / 180.0);
  const bool has_n = scan.has_normals();
  auto normals_ok = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const double c = a.dot(b);
    return (o.unsigned_normals ? std::abs(c) : c) >= cos_min;
  };
  InverseCorrespondences out;
  out.target = Eigen::MatrixX3d::Zero(n, 3);
  out.kind = Eigen::VectorXi::Zero(n);
  if (n == 0) return out;

  // Every scan point → its closest template vertex, with the 30°/50 mm rejection.
  PointIndex vertex_index(V);
  std::vector<int> match(m, -1);
  std::vector<char> refused(m, 0);
  tbb::parallel_for(Eigen::Index(0), m, [&](Eigen::Index j) {
    double d2 = 0;
    const Eigen::Vector3d p = scan.P.row(j).transpose();
    const int i = vertex_index.nearest(p, &d2);
    if (i < 0 || d2 > d2max) return;
    if (!compatible(j, i)) {
      refused[j] = 1;
      return;
    }
    if (has_n && !normals_ok(scan.N.row(j).transpose(), VN.row(i).transpose())) return;
    if (o.inverse_max_tangential_offset > 0) {
      const Eigen::Vector3d d = p - V.row(i).transpose(), nv = VN.row(i).transpose();
      if ((d - d.dot(nv) * nv).norm() > o.inverse_max_tangential_offset) return;
    }
    match[j] = i;
  });
  // Bucket the scan points per vertex (counting sort).
  std::vector<int> start(n + 1, 0), bucket;
  for (int i : match)
    if (i >= 0) ++start[i + 1];
  for (Eigen::Index i = 0; i < n; ++i) start[i + 1] += start[i];
  bucket.resize(start[n]);
  {
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (Eigen::Index j = 0; j < m; ++j)
      if (match[j] >= 0) bucket[fill[match[j]]++] = int(j);
  }
  tbb::parallel_for(Eigen::Index(0), n, [&](Eigen::Index i) {
    const Eigen::Vector3d v = V.row(i).transpose();
    const int count = start[i + 1] - start[i];
    if (count >= o.min_plane_points) {
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (int k = start[i]; k < start[i + 1]; ++k) c += scan.P.row(bucket[k]).transpose();
      c /= double(count);
      Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
      for (int k = start[i]; k < start[i + 1]; ++k) {
        const Eigen::Vector3d d = scan.P.row(bucket[k]).transpose() - c;
        C += d * d.transpose();
      }
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
      const Eigen::Vector3d nrm = es.eigenvectors().col(0);
      // A plane needs two spread directions; collinear points fall through to closest point.
      if (es.eigenvalues()(1) > 1e-12 * std::max(1.0, es.eigenvalues()(2))) {
        out.target.row(i) = (v - (v - c).dot(nrm) * nrm).transpose();
        out.kind(i) = 1;
        return;
      }
    }
    double d2 = 0;
    int j = -1;
    if (!seg) {
      j = scan_index.nearest(v, &d2);
    } else {
      std::vector<double> k2;
      const std::vector<int> near = scan_index.knn(v, 8, &k2);
      for (size_t k = 0; k < near.size() && j < 0; ++k)
        if (compatible(near[k], int(i))) j = near[k], d2 = k2[k];
    }
    if (j < 0 || d2 > d2max) return;
    if (has_n && !normals_ok(scan.N.row(j).transpose(), VN.row(i).transpose())) return;
    if (o.max_tangential_offset > 0) {
      const Eigen::Vector3d d = scan.P.row(j).transpose() - v, nv = VN.row(i).transpose();
      if ((d - d.dot(nv) * nv).norm() > o.max_tangential_offset) return;
    }
    out.target.row(i) = scan.P.row(j);
    out.kind(i) = 2;
  });
  for (Eigen::Index i = 0; i < n; ++i) {
    if (out.kind(i) == 1) ++out.plane_count;
    if (out.kind(i) == 2) ++out.closest_count;
  }
  for (char r : refused) out.refused += r;
  return out;
}

int repair_flipped_triangles(Eigen::MatrixX3d& V, const Eigen::MatrixX3d& V_ref,
                             const Eigen::MatrixX3i& F, int rings, int passes, const std::vector<int>& pinned) {
  if (V_ref.rows() != V.rows()) throw InputError("repair_flipped_triangles: V and V_ref differ in size");
  // The single fold repair (core/fold_repair.h): the reference's local shape, rotated and scaled
  // to the region's border, kept only where it leaves fewer flipped triangles; no region size cap
  // (hands of a registration can fold over thousands of vertices).
  FoldRepairOptions o;
  o.rings = rings;
  o.passes = passes;
  o.max_region_vertices = int(V.rows());
  o.pinned = pinned;
  return repair_folds(V, V_ref, F, o).flipped_before;
}

struct NonrigidRegistration::Impl {
  NonrigidOptions options;
  Eigen::MatrixX3i F;
  int n = 0;
  SparseMatrixd A;                       // 4n × 4n system matrix, fixed pattern
  Eigen::VectorXd smooth_values;         // values of S ⊗ I4 in A's pattern (zeros elsewhere)
  std::vector<int> diag_block;           // n·16 indices into A's values: block (i,i), (r,c)
  Eigen::CholmodSupernodalLLT<SparseMatrixd> solver;
  BodySegments segments;  // empty: no contact labels
};

NonrigidRegistration::NonrigidRegistration(const Mesh& tpl, const NonrigidOptions& options)
    : impl_(std::make_unique<Impl>()) {
  Impl& I = *impl_;
  I.options = options;
  I.F = tpl.F;
  I.n = int(tpl.V.rows());
  check_triangle_mesh(tpl.V, tpl.F, "template");
  const int n = I.n;

  // Edge weights: cotangent weights of the original template, clamped from below.
  SparseMatrixd L = cotangent_laplacian(tpl.V, tpl.F);
  double sum = 0;
  int count = 0;
  for (int k = 0; k < L.outerSize(); ++k)
    for (SparseMatrixd::InnerIterator it(L, k); it; ++it)
      if (it.row() != it.col() && it.value() > 0) sum += it.value(), ++count;
  const double wmin = options.min_weight_fraction * (count ? sum / count : 1.0);
  std::vector<Eigen::Triplet<double>> kt;
  for (int k = 0; k < L.outerSize(); ++k)
    for (SparseMatrixd::InnerIterator it(L, k); it; ++it)
      if (it.row() != it.col()) {
        const double w = std::max(it.value(), wmin);
        kt.emplace_back(it.row(), it.col(), -w);
        kt.emplace_back(it.row(), it.row(), w);
      }
  SparseMatrixd K(n, n);  // weighted graph Laplacian, positive semi-definite
  K.setFromTriplets(kt.begin(), kt.end());
  SparseMatrixd S = options.smoothness == Smoothness::laplacian_squared
                        ? SparseMatrixd(SparseMatrixd(K.transpose()) * K)
                        : K;

  // Pattern: S ⊗ I4 plus full 4×4 diagonal blocks (data and landmark terms).
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(S.nonZeros() * 4 + n * 16);
  for (int k = 0; k < S.outerSize(); ++k)
    for (SparseMatrixd::InnerIterator it(S, k); it; ++it)
      for (int c = 0; c < 4; ++c) t.emplace_back(4 * it.row() + c, 4 * it.col() + c, it.value());
  for (int i = 0; i < n; ++i)
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) t.emplace_back(4 * i + r, 4 * i + c, 0.0);
  I.A.resize(4 * n, 4 * n);
  I.A.setFromTriplets(t.begin(), t.end());
  I.A.makeCompressed();
  I.smooth_values = Eigen::Map<Eigen::VectorXd>(I.A.valuePtr(), I.A.nonZeros());
  I.diag_block.resize(size_t(n) * 16);
  const double* base = I.A.valuePtr();
  for (int i = 0; i < n; ++i)
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        I.diag_block[size_t(i) * 16 + r * 4 + c] =
            int(&I.A.coeffRef(4 * i + r, 4 * i + c) - base);
  I.solver.analyzePattern(I.A);
  if (I.solver.info() != Eigen::Success)
    throw NumericalError("non-rigid registration: symbolic factorisation failed");
}

NonrigidRegistration::~NonrigidRegistration() = default;
NonrigidRegistration::NonrigidRegistration(NonrigidRegistration&&) noexcept = default;
const NonrigidOptions& NonrigidRegistration::options() const { return impl_->options; }

void NonrigidRegistration::set_segments(BodySegments segments) {
  if (segments.vertex_segment.size() != impl_->n)
    throw InputError("non-rigid registration: " + std::to_string(segments.vertex_segment.size()) +
                     " segment labels for a template of " + std::to_string(impl_->n) + " vertices");
  impl_->segments = std::move(segments);
}

namespace {

using NonrigidSolver = Eigen::CholmodSupernodalLLT<SparseMatrixd>;

// The argument checks of NonrigidRegistration::fit, before any work.
void check_fit_inputs(const Eigen::MatrixX3d& V_init, const PointCloud& scan, const std::vector<Landmark>& landmarks,
                      int n) {
  if (V_init.rows() != n)
    throw InputError("non-rigid registration: initial vertices have " +
                     std::to_string(V_init.rows()) + " rows, the template has " +
                     std::to_string(n));
  if (!V_init.allFinite())
    throw InputError("non-rigid registration: initial vertices are not finite");
  check_landmarks(landmarks, n, "non-rigid registration");
  if (scan.P.rows() == 0) throw InputError("non-rigid registration: the scan has no points");
}

// The unknowns' frame: homogeneous normalised coordinates Q (q_i = [(p_i − c)/s, 1]) and the
// per-vertex affine maps X (4n by 3), starting at the identity deformation.
struct AffineFrame {
  Eigen::MatrixXd Q, X;
};

AffineFrame identity_deformation(const Eigen::MatrixX3d& V_init, double s) {
  const int n = int(V_init.rows());
  AffineFrame fr;
  // Homogeneous normalised coordinates q_i = [(p_i − c)/s, 1].
  const Eigen::RowVector3d c = V_init.colwise().mean();
  fr.Q.resize(n, 4);
  fr.Q.leftCols(3) = (V_init.rowwise() - c) / s;
  fr.Q.col(3).setOnes();
  // X_i = [s·I; c]: the identity deformation.
  fr.X = Eigen::MatrixXd::Zero(4 * n, 3);
  for (int i = 0; i < n; ++i) {
    fr.X.block<3, 3>(4 * i, 0) = s * Eigen::Matrix3d::Identity();
    fr.X.row(4 * i + 3) = c;
  }
  return fr;
}

// The vertices the affine maps X put the normalised coordinates Q at.
Eigen::MatrixX3d deformed(const Eigen::MatrixXd& Q, const Eigen::MatrixXd& X) {
  const int n = int(Q.rows());
  Eigen::MatrixX3d V(n, 3);
  for (int i = 0; i < n; ++i) V.row(i) = Q.row(i) * X.block<4, 3>(4 * i, 0);
  return V;
}

// The correspondence limits left at 0 in the options, from the scan's point spacing and the
// template's mean edge length.
void resolve_offsets(NonrigidOptions& o, const Eigen::MatrixX3d& V_init, const Eigen::MatrixX3i& F,
                     const PointIndex& scan_index) {
  if (o.max_tangential_offset <= 0) o.max_tangential_offset = 2.0 * median_point_spacing(scan_index);
  if (o.inverse_max_tangential_offset <= 0 && o.inverse_tangential_factor > 0) {
    double len = 0;
    for (int k = 0; k < F.rows(); ++k)
      for (int e = 0; e < 3; ++e) len += (V_init.row(F(k, e)) - V_init.row(F(k, (e + 1) % 3))).norm();
    o.inverse_max_tangential_offset = o.inverse_tangential_factor * len / (3.0 * F.rows());
  }
}

// Preconditioned conjugate gradients on A·X = B (3 right-hand sides, each its own CG) with the
// last numeric factorisation as the preconditioner, from X. On success X holds the solution.
bool reuse_solve(const SparseMatrixd& A, const NonrigidSolver& solver, const NonrigidOptions& o,
                 const Eigen::MatrixXd& Bm, Eigen::MatrixXd& Xm, int* its) {
  const Eigen::RowVector3d bnorm = Bm.colwise().norm();
  Eigen::MatrixXd Xc = Xm;
  Eigen::MatrixXd R = Bm - A * Xc;
  auto converged = [&](const Eigen::MatrixXd& Rm) {
    for (int k = 0; k < 3; ++k)
      if (Rm.col(k).norm() > o.reuse_tolerance * std::max(bnorm(k), 1e-300)) return false;
    return true;
  };
  if (converged(R)) return true;
  Eigen::MatrixXd Z = solver.solve(R);
  Eigen::MatrixXd P = Z;
  Eigen::RowVector3d rz = (R.array() * Z.array()).colwise().sum();
  for (int it = 1; it <= o.reuse_max_iterations; ++it) {
    *its = it;
    const Eigen::MatrixXd AP = A * P;
    const Eigen::RowVector3d pap = (P.array() * AP.array()).colwise().sum();
    for (int k = 0; k < 3; ++k) {
      if (!(pap(k) > 0)) return false;
      const double a = rz(k) / pap(k);
      Xc.col(k) += a * P.col(k);
      R.col(k) -= a * AP.col(k);
    }
    if (converged(R)) {
      if (!Xc.allFinite()) return false;
      Xm = std::move(Xc);
      return true;
    }
    Z = solver.solve(R);
    const Eigen::RowVector3d rz_new = (R.array() * Z.array()).colwise().sum();
    for (int k = 0; k < 3; ++k)
      P.col(k) = Z.col(k) + (rz(k) != 0 ? rz_new(k) / rz(k) : 0.0) * P.col(k);
    rz = rz_new;
  }
  return false;
}

// One step's weights: stiffness β, data term α, landmarks γ.
struct StepWeights {
  double beta, alpha, gamma;
};

// The step's system in place: A's values = β·smoothness plus the data, landmark and ε terms on
// the diagonal blocks, B the matching right-hand sides (ε pulls towards the current X).
void assemble_step(SparseMatrixd& A, const Eigen::VectorXd& smooth_values, const std::vector<int>& diag_block,
                   const AffineFrame& fr, const InverseCorrespondences& corr, const std::vector<Landmark>& landmarks,
                   const StepWeights& w, Eigen::MatrixXd& B) {
  const int n = int(fr.Q.rows());
  const double eps = 1e-9;  // keeps components without data or landmarks non-singular
  double* val = A.valuePtr();
  Eigen::Map<Eigen::VectorXd>(val, A.nonZeros()) = w.beta * smooth_values;
  B.setZero();
  auto add_block = [&](int i, double wt, const Eigen::RowVector3d& target) {
    const Eigen::Vector4d q = fr.Q.row(i).transpose();
    const Eigen::Matrix4d qq = wt * q * q.transpose();
    const int* idx = &diag_block[size_t(i) * 16];
    for (int r = 0; r < 4; ++r)
      for (int cc = 0; cc < 4; ++cc) val[idx[r * 4 + cc]] += qq(r, cc);
    B.block<4, 3>(4 * i, 0) += wt * q * target;
  };
  for (int i = 0; i < n; ++i) {
    const int* idx = &diag_block[size_t(i) * 16];
    for (int r = 0; r < 4; ++r) val[idx[r * 5]] += eps;
    B.block<4, 3>(4 * i, 0) += eps * fr.X.block<4, 3>(4 * i, 0);
    if (corr.kind(i) != 0) add_block(i, w.alpha, corr.target.row(i));
  }
  for (const Landmark& l : landmarks) add_block(l.vertex, w.gamma, l.target.transpose());
}

// Residuals of this step's terms at its result V, into the summary.
void record_step(NonrigidSummary& sum, const Eigen::MatrixX3d& V, const InverseCorrespondences& corr,
                 const std::vector<Landmark>& landmarks, size_t step, double beta) {
  const int n = int(V.rows());
  double d2 = 0;
  int matched = 0;
  for (int i = 0; i < n; ++i)
    if (corr.kind(i) != 0) d2 += (V.row(i) - corr.target.row(i)).squaredNorm(), ++matched;
  double l2 = 0;
  for (const Landmark& l : landmarks) l2 += (V.row(l.vertex) - l.target.transpose()).squaredNorm();
  sum.iterations = int(step) + 1;
  sum.data_rms = matched ? std::sqrt(d2 / matched) : 0.0;
  sum.landmark_rms = landmarks.empty() ? 0.0 : std::sqrt(l2 / landmarks.size());
  sum.matched_vertices = matched;
  sum.plane_matches = corr.plane_count;
  sum.final_beta = beta;
  sum.contact_refused = corr.refused;
}

}  // namespace

Eigen::MatrixX3d NonrigidRegistration::fit(const Eigen::MatrixX3d& V_init,
                                           const PointCloud& scan,
                                           const std::vector<Landmark>& landmarks,
                                           NonrigidSummary* summary,
                                           const ProgressCallback& progress) {
  Impl& I = *impl_;
  NonrigidOptions o = I.options;
  const auto t0 = std::chrono::steady_clock::now();
  const int n = I.n;
  check_fit_inputs(V_init, scan, landmarks, n);

  AffineFrame fr = identity_deformation(V_init, o.normalization_length);
  PointIndex scan_index(scan.P);
  resolve_offsets(o, V_init, I.F, scan_index);
  const std::vector<double> betas = nonrigid_schedule(o);
  Eigen::MatrixX3d V = V_init;
  // Contacts: the scan points' segments from the posed template the fit starts from.
  SegmentLabels labels;
  if (o.contact_segments && I.segments.count() > 1) {
    labels.segments = &I.segments;
    PointSegmentOptions so;
    so.unsigned_normals = o.unsigned_normals;
    labels.point_segment = point_segments(scan.P, scan.has_normals() ? scan.N : Eigen::MatrixX3d(), V_init,
                                          vertex_normals(V_init, I.F), I.segments.vertex_segment, so);
  }
  NonrigidSummary sum;
  Eigen::MatrixXd B(4 * n, 3);
  bool have_factor = false;
  for (size_t step = 0; step < betas.size(); ++step) {
    report_progress(progress, double(step) / double(betas.size()), "non-rigid fit");
    const double beta = betas[step], gamma = std::max(o.landmark_factor * beta, o.landmark_floor), alpha = o.alpha;
    const Eigen::MatrixX3d VN = vertex_normals(V, I.F);
    auto tc = std::chrono::steady_clock::now();
    const InverseCorrespondences corr = inverse_correspondences(V, VN, scan, scan_index, o, labels.segments ? &labels : nullptr);
    auto ts = std::chrono::steady_clock::now();
    sum.correspondence_seconds += std::chrono::duration<double>(ts - tc).count();

    assemble_step(I.A, I.smooth_values, I.diag_block, fr, corr, landmarks, {beta, alpha, gamma}, B);
    bool solved = false;
    if (have_factor && o.reuse_max_iterations > 0) {
      int its = 0;
      solved = reuse_solve(I.A, I.solver, o, B, fr.X, &its);
      sum.reuse_iterations += its;
    }
    if (!solved) {
      I.solver.factorize(I.A);
      if (I.solver.info() != Eigen::Success)
        throw NumericalError("non-rigid registration: factorisation failed at step " +
                             std::to_string(step) + " (β = " + std::to_string(beta) + ")");
      have_factor = true;
      ++sum.factorizations;
      Eigen::MatrixXd Xn = I.solver.solve(B);
      if (I.solver.info() != Eigen::Success || !Xn.allFinite())
        throw NumericalError("non-rigid registration: solve failed at step " +
                             std::to_string(step));
      fr.X = std::move(Xn);
    }
    sum.solve_seconds +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - ts).count();
    V = deformed(fr.Q, fr.X);
    record_step(sum, V, corr, landmarks, step, beta);
  }
  report_progress(progress, 1.0, "non-rigid fit");
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (summary) *summary = sum;
  return V;
}

}  // namespace bodymodel
