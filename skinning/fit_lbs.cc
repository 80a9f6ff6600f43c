#include "skinning/fit_lbs.h"

#include <chrono>
#include <cmath>
#include <mutex>
#include <sstream>

#include <Eigen/Cholesky>
#include <tbb/parallel_for.h>

#include "core/error.h"

namespace bodymodel {

std::string LbsFitSummary::brief() const {
  std::ostringstream s;
  s << "SSD fit: " << vertices << " vertices, " << poses << " poses, " << bones << " bones, ≤"
    << max_influences << " influences; residual RMS " << rms_residual << ", max " << max_residual
    << "; " << seconds << " s";
  return s.str();
}

namespace {

// Lawson–Hanson active set on the normal equations, for Mat/Vec either dynamic or with a fixed
// maximum size (no heap allocation: the per-vertex SSD solve runs millions of times).
template <typename Mat, typename Vec>
Vec nnls_impl(const Mat& H, const Vec& g) {
  const Eigen::Index n = g.size();
  Vec x = Vec::Zero(n);
  bool passive[Mat::MaxRowsAtCompileTime > 0 ? Mat::MaxRowsAtCompileTime : 1] = {};
  std::vector<bool> passive_dyn;
  auto is_p = [&](Eigen::Index i) -> bool {
    return Mat::MaxRowsAtCompileTime > 0 ? passive[i] : static_cast<bool>(passive_dyn[static_cast<size_t>(i)]);
  };
  auto set_p = [&](Eigen::Index i, bool v) {
    if (Mat::MaxRowsAtCompileTime > 0) passive[i] = v;
    else passive_dyn[static_cast<size_t>(i)] = v;
  };
  if (Mat::MaxRowsAtCompileTime <= 0) passive_dyn.assign(static_cast<size_t>(n), false);
  const double scale = std::max(H.diagonal().cwiseAbs().maxCoeff(), 1e-300);
  const double tol = 1e-12 * scale * std::max(1.0, g.cwiseAbs().maxCoeff() / scale);
  Eigen::Index idx[Mat::MaxRowsAtCompileTime > 0 ? Mat::MaxRowsAtCompileTime : 1];
  std::vector<Eigen::Index> idx_dyn(Mat::MaxRowsAtCompileTime > 0 ? 0 : static_cast<size_t>(n));
  Eigen::Index* P = Mat::MaxRowsAtCompileTime > 0 ? idx : idx_dyn.data();
  Mat Hp;
  Vec gp, s;
  auto solve_passive = [&]() {
    Eigen::Index m = 0;
    for (Eigen::Index i = 0; i < n; ++i)
      if (is_p(i)) P[m++] = i;
    Hp.resize(m, m);
    gp.resize(m);
    for (Eigen::Index a = 0; a < m; ++a) {
      gp(a) = g(P[a]);
      for (Eigen::Index b = 0; b < m; ++b) Hp(a, b) = H(P[a], P[b]);
      Hp(a, a) += 1e-14 * scale;
    }
    const Vec sp = Hp.ldlt().solve(gp);
    s.setZero(n);
    for (Eigen::Index a = 0; a < m; ++a) s(P[a]) = sp(a);
  };
  for (int outer = 0; outer < 3 * n + 10; ++outer) {
    const Vec w = g - H * x;   // negative gradient
    Eigen::Index j = -1;
    double best = tol;
    for (Eigen::Index i = 0; i < n; ++i)
      if (!is_p(i) && w(i) > best) best = w(i), j = i;
    if (j < 0) break;
    set_p(j, true);
    for (int inner = 0; inner < 3 * n + 10; ++inner) {
      solve_passive();
      double alpha = 1.0;
      bool feasible = true;
      for (Eigen::Index i = 0; i < n; ++i)
        if (is_p(i) && s(i) <= 0) {
          feasible = false;
          const double d = x(i) - s(i);
          if (d > 0) alpha = std::min(alpha, x(i) / d);
        }
      if (feasible) break;
      x += alpha * (s - x);
      for (Eigen::Index i = 0; i < n; ++i)
        if (is_p(i) && x(i) <= 1e-15) {
          set_p(i, false);
          x(i) = 0;
        }
    }
    x = s.cwiseMax(0.0);
  }
  return x;
}

constexpr int kSmall = 32;
using SmallMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kSmall, kSmall>;
using SmallVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kSmall, 1>;

}  // namespace

Eigen::VectorXd nonnegative_least_squares(const Eigen::MatrixXd& H, const Eigen::VectorXd& g) {
  if (g.size() <= kSmall) return nnls_impl<SmallMat, SmallVec>(SmallMat(H), SmallVec(g));
  return nnls_impl<Eigen::MatrixXd, Eigen::VectorXd>(H, g);
}

void rig_residuals(const SkinningRig& rig, const SkinningExamples& ex, double* rms, double* max) {
  double sum = 0, mx = 0;
  for (int p = 0; p < ex.pose_count(); ++p) {
    const Eigen::MatrixX3d X = evaluate_rig(rig, ex.transforms[static_cast<size_t>(p)]);
    const Eigen::VectorXd e = (X - ex.poses[static_cast<size_t>(p)]).rowwise().norm();
    sum += e.squaredNorm();
    mx = std::max(mx, e.maxCoeff());
  }
  if (rms) *rms = std::sqrt(sum / std::max(1.0, double(ex.pose_count()) * ex.vertex_count()));
  if (max) *max = mx;
}

SkinningRig base_lbs_rig(const SkinningExamples& ex, const SkinningRig* base, int max_influences,
                         const std::string& who) {
  if (base) {
    if (base->method != SkinningMethod::lbs || base->vertex_count() != ex.vertex_count() ||
        base->bone_count != ex.bone_count())
      throw InputError(who + ": the base rig must be an ssd rig with the examples' " +
                       std::to_string(ex.vertex_count()) + " vertices and " +
                       std::to_string(ex.bone_count()) + " bones");
    return *base;
  }
  LbsFitOptions lo;
  lo.max_influences = max_influences;
  lo.require_rigid = false;
  return fit_lbs(ex, {}, lo);
}

SkinningRig fit_lbs(const SkinningExamples& ex, const Eigen::MatrixXi& influences_in,
                    const LbsFitOptions& options, LbsFitSummary* summary,
                    const ProgressCallback& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  validate_examples(ex, options.require_rigid, options.rigid_tolerance);
  const Eigen::Index n = ex.rest.rows();
  const int B = ex.bone_count(), P = ex.pose_count();
  Eigen::MatrixXi I;
  if (influences_in.size()) {
    I = influences_in;
  } else if (options.influence_candidates > options.max_influences &&
             options.max_influences < B) {
    LbsFitOptions wide = options;
    wide.influence_candidates = 0;
    const SkinningRig all = fit_lbs(ex, choose_influences(ex, options.influence_candidates), wide);
    I = lbs_rig_from_weights(ex.rest, dense_weights(all), options.max_influences, 0.0).influences;
  } else {
    I = choose_influences(ex, options.max_influences);
  }
  if (I.rows() != n)
    throw InputError("fit_lbs: influence sets have " + std::to_string(I.rows()) +
                     " rows, expected one per vertex (" + std::to_string(n) + ")");
  if (I.size() && (I.maxCoeff() >= B || I.minCoeff() < -1))
    throw InputError("fit_lbs: influence sets name bones outside 0.." + std::to_string(B - 1));
  const Eigen::Index K = I.cols();
  SkinningRig rig;
  rig.method = SkinningMethod::lbs;
  rig.bone_count = B;
  rig.rest = ex.rest;
  rig.influences = Eigen::MatrixXi::Constant(n, K, -1);
  rig.coefficients = Eigen::MatrixXd::Zero(n, K);

  // H_kl = Σ_p ω_p² (M_k(p) ṽ)·(M_l(p) ṽ) = ṽᵀ G_kl ṽ with G_kl = Σ_p ω_p² M_k(p)ᵀ M_l(p) (4 × 4, M as its
  // 3 × 4 rows): the pose sum done once per bone pair instead of once per vertex (the per-pose form
  // was most of the fit's own time on 30 Vlasic frames, 16 candidates).
  std::vector<Eigen::Matrix4d> G;
  if (options.pairwise_moments) {
    G.assign(static_cast<size_t>(B) * B, Eigen::Matrix4d::Zero());
    for (int p = 0; p < P; ++p) {
      const double w2 = ex.pose_weight(p) * ex.pose_weight(p);
      const auto& T = ex.transforms[static_cast<size_t>(p)];
      for (int k = 0; k < B; ++k) {
        const Eigen::Matrix<double, 3, 4> Mk = T[static_cast<size_t>(k)].matrix().topRows<3>();
        for (int l = k; l < B; ++l)
          G[static_cast<size_t>(k) * B + l].noalias() += w2 * Mk.transpose() * T[static_cast<size_t>(l)].matrix().topRows<3>();
      }
    }
    for (int k = 0; k < B; ++k)
      for (int l = 0; l < k; ++l) G[static_cast<size_t>(k) * B + l] = G[static_cast<size_t>(l) * B + k].transpose();
  }
  const Eigen::Index chunk = std::max<Eigen::Index>(1024, n / 20);
  for (Eigen::Index start = 0; start < n; start += chunk) {
    report_progress(progress, double(start) / n, "SSD weights");
    const Eigen::Index stop = std::min(n, start + chunk);
    tbb::parallel_for(tbb::blocked_range<Eigen::Index>(start, stop, 64), [&](const auto& r) {
      for (Eigen::Index i = r.begin(); i < r.end(); ++i) {
        std::vector<int> bones;
        for (Eigen::Index k = 0; k < K; ++k)
          if (I(i, k) >= 0 && std::find(bones.begin(), bones.end(), I(i, k)) == bones.end())
            bones.push_back(I(i, k));
        const auto m = static_cast<Eigen::Index>(bones.size());
        if (m == 0) throw InputError("fit_lbs: vertex " + std::to_string(i) + " has no influence");
        const Eigen::Vector3d v = ex.rest.row(i).transpose();
        // Normal equations directly: y_pk = ω_p M_k(p) v, H = Σ_p Y_pᵀY_p, g = Σ_p Y_pᵀ ω_p q_p.
        auto solve = [&](auto H, auto g, auto Y) -> Eigen::VectorXd {
          H.setZero(m, m);
          g.setZero(m);
          Y.resize(3, m);
          const bool moments = !G.empty();
          if (moments) {
            const Eigen::Vector4d vh(v(0), v(1), v(2), 1.0);
            for (Eigen::Index l = 0; l < m; ++l)
              for (Eigen::Index k = 0; k <= l; ++k)
                H(k, l) = vh.dot(G[static_cast<size_t>(bones[static_cast<size_t>(k)]) * B + bones[static_cast<size_t>(l)]] * vh);
          }
          for (int p = 0; p < P; ++p) {
            const double w = ex.pose_weight(p);
            const auto& T = ex.transforms[static_cast<size_t>(p)];
            for (Eigen::Index k = 0; k < m; ++k) Y.col(k) = w * (T[static_cast<size_t>(bones[static_cast<size_t>(k)])] * v);
            // The upper triangle only, by hand: at most 32 × 32 with depth 3, where Eigen's GEMM path
            // (packing, blocking) cost as much as the rest of the fit.
            if (!moments)
              for (Eigen::Index l = 0; l < m; ++l)
                for (Eigen::Index k = 0; k <= l; ++k) H(k, l) += Y.col(k).dot(Y.col(l));
            g.noalias() += Y.transpose() * (w * ex.poses[static_cast<size_t>(p)].row(i).transpose());
          }
          for (Eigen::Index l = 0; l < m; ++l)
            for (Eigen::Index k = l + 1; k < m; ++k) H(k, l) = H(l, k);
          const double omega2 = options.sum_to_one_weight * options.sum_to_one_weight * std::max(H.trace() / m, 1e-300);
          H.array() += omega2;
          g.array() += omega2;
          return nnls_impl<decltype(H), decltype(g)>(H, g);
        };
        Eigen::VectorXd w = m <= kSmall ? solve(SmallMat(), SmallVec(), Eigen::Matrix<double, 3, Eigen::Dynamic, 0, 3, kSmall>())
                                        : solve(Eigen::MatrixXd(), Eigen::VectorXd(), Eigen::Matrix3Xd());
        const double s = w.sum();
        if (!(s > 0) || !w.allFinite()) {
          w.setZero();
          w(0) = 1;
        } else {
          w /= s;
        }
        for (Eigen::Index k = 0; k < m; ++k) {
          rig.influences(i, k) = bones[static_cast<size_t>(k)];
          rig.coefficients(i, k) = w(k);
        }
      }
    });
  }
  report_progress(progress, 1.0, "SSD weights");
  if (summary) {
    summary->vertices = static_cast<int>(n);
    summary->poses = P;
    summary->bones = B;
    summary->max_influences = static_cast<int>(K);
    summary->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    rig_residuals(rig, ex, &summary->rms_residual, &summary->max_residual);
  }
  return rig;
}

}  // namespace bodymodel
