#include "skinning/fit_mwe.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <sstream>

#include <Eigen/Eigenvalues>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/geometry.h"
#include "skinning/fit_animation_space.h"
#include "skinning/fit_lbs.h"

namespace bodymodel {

std::string MweFitSummary::brief() const {
  std::ostringstream s;
  s << "MWE fit: " << vertices << " vertices, " << poses << " poses (≥" << unique_poses_min
    << " unique per vertex), ≤" << max_influences << " influences, " << mean_components
    << " components on average; residual RMS " << rms_residual << ", max " << max_residual << "; "
    << seconds << " s (+ base " << base_seconds << " s)";
  return s.str();
}

SkinningRig animation_space_as_mwe(const SkinningRig& as, const SkinningRig& lbs) {
  if (as.method != SkinningMethod::animation_space || lbs.method != SkinningMethod::lbs ||
      as.vertex_count() != lbs.vertex_count() || as.influences != lbs.influences)
    throw InputError("animation_space_as_mwe: expected an as rig and the ssd rig it was fitted over (same influences)");
  SkinningRig m = lbs_as_mwe(lbs);
  for (Eigen::Index i = 0; i < as.rest.rows(); ++i) {
    const Eigen::Vector4d v(as.rest(i, 0), as.rest(i, 1), as.rest(i, 2), 1.0);
    for (Eigen::Index k = 0; k < as.influences.cols(); ++k) {
      if (as.influences(i, k) < 0) continue;
      for (int c = 0; c < 4; ++c) {
        if (v(c) == 0) continue;   // keeps the SSD weight (see the header)
        const double w = as.coefficients(i, 4 * k + c) / v(c);
        for (int j = 0; j < 3; ++j) m.coefficients(i, 12 * k + 4 * j + c) = w;
      }
    }
  }
  return m;
}

SkinningRig fit_mwe(const SkinningExamples& ex, const SkinningRig* base_lbs, const MweFitOptions& options,
                    MweFitSummary* summary, const ProgressCallback& progress) {
  return fit_mwe_path(ex, base_lbs, options, {options.ridge_scale}, summary, progress).front();
}

namespace {

// What every vertex's solve reads: the examples, the SSD rig and options, the ridge scales and
// their unit, the base rig's positions in every pose and the per-bone pose distances.
struct MweFit {
  const SkinningExamples& ex;
  const SkinningRig& lbs;
  const MweFitOptions& options;
  const std::vector<double>& scales;
  double unit;
  std::vector<Eigen::MatrixX3d> base_pos;   // per pose
  std::vector<Eigen::MatrixXd> D;           // per bone, P by P pose distances
};

// One vertex's problem: its refined slots, the groups of duplicate poses, the influence maps and
// its homogeneous rest position.
struct MweVertex {
  Eigen::Index i;
  std::vector<Eigen::Index> slots;
  std::vector<std::vector<int>> groups;
  Eigen::VectorXd mu;
  Eigen::Vector4d v;
};

// The argument checks of fit_mwe_path that need no base rig, so a bad call fails at once.
void check_mwe_inputs(const SkinningExamples& ex, const MweFitOptions& options, const std::vector<double>& scales) {
  validate_examples(ex, false);
  if (scales.empty()) throw InputError("mwe: no ridge scale given");
  for (double s : scales)
    if (!(s >= 0)) throw InputError("mwe: ridge scale s must be ≥ 0, found " + std::to_string(s));
  if (options.components < 0) throw InputError("mwe: components must be ≥ 0");
  if (options.delta_influences < 0) throw InputError("mwe: delta influences must be ≥ 0");
}

// The base rig as MWE coefficients (ssd, none, rigid or animation space), which the fitted
// deltas are added to.
SkinningRig mwe_base_rig(const SkinningExamples& ex, const SkinningRig& lbs, const MweFitOptions& options) {
  const Eigen::Index n = ex.rest.rows();
  SkinningRig base = lbs_as_mwe(lbs);
  if (options.base == MweBase::none) base.coefficients.setZero();
  if (options.base == MweBase::rigid) {
    base.coefficients.setZero();
    for (Eigen::Index i = 0; i < n; ++i) {
      Eigen::Index best = 0;
      lbs.coefficients.row(i).maxCoeff(&best);
      base.coefficients.row(i).segment<12>(12 * best).setOnes();
    }
  }
  if (options.base == MweBase::animation_space) {
    AnimationSpaceFitOptions ao;
    ao.ridge = options.base_as_ridge;
    base = animation_space_as_mwe(fit_animation_space(ex, &lbs, ao), lbs);
  }
  return base;
}

// Per-bone pose distances for duplicate detection: D[b](p, q) = max entry difference, the
// translation scaled by the rest pose's diagonal.
std::vector<Eigen::MatrixXd> pose_distances(const SkinningExamples& ex, double diag) {
  const int P = ex.pose_count(), B = ex.bone_count();
  std::vector<Eigen::MatrixXd> D(static_cast<size_t>(B), Eigen::MatrixXd::Zero(P, P));
  for (int b = 0; b < B; ++b)
    for (int p = 0; p < P; ++p)
      for (int q = p + 1; q < P; ++q) {
        Eigen::Matrix<double, 3, 4> d = ex.transforms[static_cast<size_t>(p)][static_cast<size_t>(b)].affine() -
                                        ex.transforms[static_cast<size_t>(q)][static_cast<size_t>(b)].affine();
        d.col(3) /= diag;
        D[static_cast<size_t>(b)](p, q) = D[static_cast<size_t>(b)](q, p) = d.cwiseAbs().maxCoeff();
      }
  return D;
}

// Vertex i's problem: the refined slots (every used slot, or the delta_influences largest SSD
// weights), its duplicate poses grouped (step 1) and its influence maps μ_k (§4.2).
MweVertex mwe_vertex(const MweFit& f, Eigen::Index i) {
  const SkinningRig& lbs = f.lbs;
  const MweFitOptions& options = f.options;
  const int P = f.ex.pose_count();
  MweVertex vx;
  vx.i = i;
  // The refined slots: every used slot, or the delta_influences largest SSD weights.
  std::vector<Eigen::Index>& slots = vx.slots;
  for (Eigen::Index k = 0; k < lbs.influences.cols(); ++k)
    if (lbs.influences(i, k) >= 0) slots.push_back(k);
  if (options.delta_influences > 0 && static_cast<int>(slots.size()) > options.delta_influences) {
    std::stable_sort(slots.begin(), slots.end(), [&](Eigen::Index a, Eigen::Index b) {
      return lbs.coefficients(i, a) > lbs.coefficients(i, b);
    });
    slots.resize(static_cast<size_t>(options.delta_influences));
  }
  const auto nb = static_cast<Eigen::Index>(slots.size());
  vx.v = Eigen::Vector4d(f.ex.rest(i, 0), f.ex.rest(i, 1), f.ex.rest(i, 2), 1.0);
  // 1. group duplicate poses for this vertex's bones.
  std::vector<int> group(static_cast<size_t>(P), -1);
  std::vector<std::vector<int>>& groups = vx.groups;
  for (int p = 0; p < P; ++p) {
    if (group[static_cast<size_t>(p)] >= 0) continue;
    group[static_cast<size_t>(p)] = static_cast<int>(groups.size());
    groups.push_back({p});
    for (int q = p + 1; q < P; ++q) {
      if (group[static_cast<size_t>(q)] >= 0) continue;
      double dmax = 0;
      for (Eigen::Index s = 0; s < nb; ++s)
        dmax = std::max(dmax, f.D[static_cast<size_t>(lbs.influences(i, slots[static_cast<size_t>(s)]))](p, q));
      if (dmax <= options.duplicate_tolerance) {
        group[static_cast<size_t>(q)] = group[static_cast<size_t>(p)];
        groups.back().push_back(q);
      }
    }
  }
  // Influence maps μ_k (§4.2).
  vx.mu = Eigen::VectorXd::Ones(nb);
  if (options.influence_map_floor > 0)
    for (Eigen::Index s = 0; s < nb; ++s)
      vx.mu(s) = std::max(options.influence_map_floor, lbs.coefficients(i, slots[static_cast<size_t>(s)]));
  return vx;
}

// Coordinate j of one vertex: the pose-group system, PCA on its columns (step 3) and the local
// ridge regression (step 4) for every scale, added into each rig; returns the components used.
Eigen::Index fit_mwe_coordinate(const MweFit& f, const MweVertex& vx, int j, std::vector<SkinningRig>& rigs) {
  const SkinningExamples& ex = f.ex;
  const MweFitOptions& options = f.options;
  const Eigen::Index i = vx.i;
  const auto& slots = vx.slots;
  const auto& groups = vx.groups;
  const Eigen::VectorXd& mu = vx.mu;
  const Eigen::Vector4d& v = vx.v;
  const auto nb = static_cast<Eigen::Index>(slots.size());
  const auto m = static_cast<Eigen::Index>(groups.size());
  const size_t S = f.scales.size();
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(m, 4 * nb);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(m);
  for (Eigen::Index g = 0; g < m; ++g) {
    const auto& members = groups[static_cast<size_t>(g)];
    double omega = 0;
    for (int p : members) {
      omega = std::max(omega, ex.pose_weight(p));
      for (Eigen::Index s = 0; s < nb; ++s) {
        const auto& M = ex.transforms[static_cast<size_t>(p)][static_cast<size_t>(f.lbs.influences(i, slots[static_cast<size_t>(s)]))];
        for (int c = 0; c < 4; ++c) A(g, 4 * s + c) += mu(s) * M.matrix()(j, c) * v(c);
      }
      b(g) += ex.poses[static_cast<size_t>(p)](i, j) - f.base_pos[static_cast<size_t>(p)](i, j);
    }
    const double inv = 1.0 / double(members.size());
    A.row(g) *= inv * omega;
    b(g) *= inv * omega;
  }
  // 3. PCA on the columns of A.
  const Eigen::Index cols = 4 * nb;
  if (m < 2) return 0;
  const Eigen::RowVectorXd mean = A.colwise().mean();
  const Eigen::MatrixXd Ac = A.rowwise() - mean;
  const Eigen::MatrixXd cov = Ac.transpose() * Ac / double(m - 1);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(cov);
  const Eigen::VectorXd ev = eig.eigenvalues().reverse();          // decreasing
  const Eigen::MatrixXd evec = eig.eigenvectors().rowwise().reverse();
  const double total = std::max(ev.cwiseMax(0.0).sum(), 0.0);
  const double zero = 1e-12 * std::max(ev(0), 0.0);
  Eigen::Index p = 0;
  if (total > 0) {
    if (options.components > 0) {
      p = std::min<Eigen::Index>(options.components, cols);
    } else {
      double acc = 0;
      while (p < cols && acc < options.variance_kept * total) acc += std::max(ev(p++), 0.0);
    }
    while (p > 0 && ev(p - 1) <= zero) --p;   // zero variance → λ = ∞ → dropped
  }
  if (p == 0) return 0;
  const Eigen::MatrixXd E = evec.leftCols(p);
  const Eigen::MatrixXd C = A * E;
  // 4. local ridge regression, λ_h = s / σ²(c_h): scaled by σ_h = √σ²(c_h), the system
  //    (CᵀC + sΛ) w_c = Cᵀb becomes (S + sI) y = σ ⊙ Cᵀb with w_c = σ ⊙ y.
  const Eigen::RowVectorXd cmean = C.colwise().mean();
  Eigen::VectorXd sd(p);
  for (Eigen::Index h = 0; h < p; ++h)
    sd(h) = std::sqrt(std::max((C.col(h).array() - cmean(h)).square().sum() / double(m - 1), 1e-300));
  const Eigen::MatrixXd Sm = sd.asDiagonal() * (C.transpose() * C) * sd.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Sm);
  const Eigen::VectorXd mu_s = es.eigenvalues().cwiseMax(0.0);
  const Eigen::VectorXd rhs = es.eigenvectors().transpose() * (sd.asDiagonal() * (C.transpose() * b));
  for (size_t k = 0; k < S; ++k) {
    const double s_used = f.scales[k] * f.unit;
    const double top = mu_s.maxCoeff() + s_used;
    Eigen::VectorXd y = Eigen::VectorXd::Zero(p);
    for (Eigen::Index h = 0; h < p; ++h)
      if (mu_s(h) + s_used > options.singular_value_tolerance * top) y(h) = rhs(h) / (mu_s(h) + s_used);
    const Eigen::VectorXd wc = sd.asDiagonal() * (es.eigenvectors() * y);
    const Eigen::VectorXd wfull = E * wc;
    for (Eigen::Index s = 0; s < nb; ++s)
      for (int c = 0; c < 4; ++c)
        rigs[k].coefficients(i, 12 * slots[static_cast<size_t>(s)] + 4 * j + c) += mu(s) * wfull(4 * s + c);
  }
  return p;
}

}  // namespace

std::vector<SkinningRig> fit_mwe_path(const SkinningExamples& ex, const SkinningRig* base_lbs,
                                      const MweFitOptions& options, const std::vector<double>& scales,
                                      MweFitSummary* summary, const ProgressCallback& progress) {
  auto t0 = std::chrono::steady_clock::now();
  check_mwe_inputs(ex, options, scales);
  const SkinningRig lbs = base_lbs_rig(ex, base_lbs, options.max_influences, "mwe");
  const Eigen::Index n = ex.rest.rows(), K = lbs.influences.cols();
  const int P = ex.pose_count();
  const double diag = std::max(bounding_box_diagonal(ex.rest), 1e-300);
  const double unit = options.ridge_scale_relative ? std::pow(diag, 4) : 1.0;
  const size_t S = scales.size();

  // Base rig as MWE coefficients (folded in at the end) and its positions in every pose.
  const SkinningRig base = mwe_base_rig(ex, lbs, options);
  const double base_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  t0 = std::chrono::steady_clock::now();
  MweFit f{ex, lbs, options, scales, unit, std::vector<Eigen::MatrixX3d>(static_cast<size_t>(P)), {}};
  for (int p = 0; p < P; ++p)
    f.base_pos[static_cast<size_t>(p)] = evaluate_rig(base, ex.transforms[static_cast<size_t>(p)]);
  f.D = pose_distances(ex, diag);

  std::vector<SkinningRig> rigs(S, base);
  for (auto& r : rigs) r.method = SkinningMethod::mwe;
  std::atomic<long long> components_total{0};
  std::atomic<int> unique_min{P};
  const Eigen::Index chunk = std::max<Eigen::Index>(1024, n / 20);
  for (Eigen::Index start = 0; start < n; start += chunk) {
    report_progress(progress, double(start) / n, "MWE weights");
    const Eigen::Index stop = std::min(n, start + chunk);
    tbb::parallel_for(tbb::blocked_range<Eigen::Index>(start, stop, 32), [&](const auto& r) {
      long long comp_local = 0;
      for (Eigen::Index i = r.begin(); i < r.end(); ++i) {
        const MweVertex vx = mwe_vertex(f, i);
        const auto m = static_cast<Eigen::Index>(vx.groups.size());
        {
          int cur = unique_min.load();
          while (m < cur && !unique_min.compare_exchange_weak(cur, static_cast<int>(m))) {
          }
        }
        for (int j = 0; j < 3; ++j) comp_local += fit_mwe_coordinate(f, vx, j, rigs);
      }
      components_total += comp_local;
    });
  }
  report_progress(progress, 1.0, "MWE weights");
  for (const auto& r : rigs)
    if (!r.coefficients.allFinite()) throw NumericalError("mwe: the ridge solve produced non-finite weights");
  if (summary) {
    summary->vertices = static_cast<int>(n);
    summary->poses = P;
    summary->unique_poses_min = unique_min.load();
    summary->max_influences = static_cast<int>(K);
    summary->mean_components = double(components_total.load()) / (3.0 * double(n));
    summary->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    summary->base_seconds = base_seconds;
    rig_residuals(rigs.back(), ex, &summary->rms_residual, &summary->max_residual);
  }
  return rigs;
}

}  // namespace bodymodel
