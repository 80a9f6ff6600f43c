#include "model/fit.h"

#include <Eigen/CholmodSupport>
#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <tbb/parallel_for.h>


#include "core/error.h"
#include "encoding/deformation_gradient.h"
#include "model/format.h"

namespace bodymodel {

namespace {

using SparseMatrixd = Eigen::SparseMatrix<double>;
using Cholesky = Eigen::CholmodSupernodalLLT<SparseMatrixd, Eigen::Lower>;

Eigen::Matrix3d skew(const Eigen::Vector3d& w) {
  Eigen::Matrix3d S;
  S << 0, -w(2), w(1), w(2), 0, -w(0), -w(1), w(0), 0;
  return S;
}

Eigen::Vector3d axial(const Eigen::Matrix3d& W) {  // of a skew-symmetric W (twice its skew part's)
  return Eigen::Vector3d(W(2, 1), W(0, 2), W(1, 0));
}

// Right Jacobian of SO(3): exp(φ + ε) ≈ exp(φ) exp([J_r(φ) ε]×).
Eigen::Matrix3d right_jacobian(const Eigen::Vector3d& phi) {
  const double t2 = phi.squaredNorm(), t = std::sqrt(t2);
  double a, b;  // (1 − cos θ)/θ², (θ − sin θ)/θ³
  if (t < 1e-4) {
    a = 0.5 - t2 / 24;
    b = 1.0 / 6 - t2 / 120;
  } else {
    a = (1 - std::cos(t)) / t2;
    b = (t - std::sin(t)) / (t2 * t);
  }
  const Eigen::Matrix3d K = skew(phi);
  return Eigen::Matrix3d::Identity() - a * K + b * K * K;
}

Eigen::Matrix3d stretch_of(const double* s6) {
  Eigen::Matrix3d S;
  S << s6[0], s6[1], s6[2], s6[1], s6[3], s6[4], s6[2], s6[4], s6[5];
  return S;
}

double percentile(std::vector<double> v, double p) {  // numpy's default (linear)
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const double pos = p / 100.0 * static_cast<double>(v.size() - 1);
  const size_t lo = static_cast<size_t>(std::floor(pos));
  const size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

using Clock = std::chrono::steady_clock;

}  // namespace

void ModelFitOptions::validate() const {
  if (components == 0 || components < -1)
    throw InputError(fmt::format("fit: components must be ≥ 1 or −1 (all), got {}", components));
  if (continuation_iterations < 0)
    throw InputError(fmt::format("fit: continuation_iterations must be ≥ 0, got {}", continuation_iterations));
  if (max_iterations < 0) throw InputError(fmt::format("fit: max_iterations must be ≥ 0, got {}", max_iterations));
  if (!(relative_tolerance >= 0) || !(step_tolerance_mm >= 0))
    throw InputError("fit: tolerances must be ≥ 0");
  if (!(prior_weight >= 0) || !std::isfinite(prior_weight))
    throw InputError(fmt::format("fit: prior_weight must be ≥ 0 and finite, got {}", prior_weight));
}

std::string ModelFitSummary::report() const {
  return fmt::format(
      "{} components: mean vertex error {:.3f} (start {:.3f}), RMS {:.3f}, p95 {:.3f}, max {:.3f}; {} "
      "iterations, {} Jacobians ({:.2f} s), {} decodes ({:.2f} s), {:.2f} s{}",
      components, mean_mm, start_mean_mm, rms_mm, p95_mm, max_mm, iterations, jacobians, jacobian_seconds,
      evaluations, decode_seconds, seconds,
      converged ? "" : " (iteration limit)");
}

// Everything that depends only on the template: slots, the rotation system's pattern and where
// each slot's 3×3 block lives in it.
struct ModelFitter::Impl {
  int nf = 0, nv = 0, n = 0;      // triangles, vertices, unknown triangles
  int fixed = 0;                  // the fixed triangle (the decoder's: smallest index)
  std::vector<int> unknown;       // #F → unknown index or −1
  struct Slot {
    int f, k, g;                  // slot 3f + k, neighbour g
    bool f_high;                  // unknown(f) > unknown(g): the slot's block is stored as is
    std::array<int, 9> pos;       // value positions of the lower block (row-major a, c)
  };
  std::vector<Slot> slots;        // slots with a neighbour
  std::vector<std::array<int, 9>> diag_pos;  // per unknown, −1 above the diagonal
  std::vector<double> diag_count; // per unknown: I × (number of slots touching it)
  SparseMatrixd pattern;          // 3n × 3n, lower triangle
  std::vector<char> referenced;   // #V: vertex used by a triangle
  std::vector<Eigen::Matrix3d> identity;  // #F identities (stretch argument of solve_positions)

  // Per-evaluation state.
  struct State {
    std::vector<Eigen::Matrix3d> slot_R, S, R, Pinv;  // R̂ per slot, S_f, R_f, (tr P − P)⁻¹
    Eigen::MatrixXd X;                                // 3n × 3 rotation-system solution
  };
};

// Per-fit workspace: the rotation-system solver (analysed once: the pattern never changes) and
// the state of the last evaluation, whose factorisation the solver holds.
struct ModelFitter::Workspace {
  std::unique_ptr<Cholesky> chol;
  Impl::State state;       // of the last evaluate(): its factorisation is in chol
  Eigen::VectorXd x;       // its encoding values
};

ModelFitter::ModelFitter(std::shared_ptr<const EncodingTemplate> tmpl, std::shared_ptr<const EncodingMean> mean,
                         const Pca& pca)
    : tmpl_(std::move(tmpl)), mean_(std::move(mean)), pca_(pca),
      decoder_(tmpl_, [] {
        DecoderOptions o;
        o.align_to_template = false;
        return o;
      }()),
      impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.nf = tmpl_->triangle_count();
  m.nv = tmpl_->vertex_count();
  if (pca_.dimension() != tmpl_->encoding_size())
    throw InputError(fmt::format("fit: the PCA has dimension {}, the template's encoding has {} values",
                                 pca_.dimension(), tmpl_->encoding_size()));
  if (decoder_.component_count() != 1)
    throw InputError(fmt::format("fit: the template has {} separate surface components; the fit places "
                                 "one rigid body and needs a connected mesh",
                                 decoder_.component_count()));
  const Eigen::MatrixX3i& TT = tmpl_->adjacency();
  const Eigen::MatrixX3i& F = tmpl_->faces();
  m.fixed = 0;  // the decoder fixes the smallest triangle index of each (here: the one) component
  m.unknown.assign(m.nf, -1);
  for (int f = 0; f < m.nf; ++f)
    if (f != m.fixed) m.unknown[f] = m.n++;
  m.diag_count.assign(m.n, 0.0);
  std::vector<Eigen::Triplet<double>> trip;
  for (int p = 0; p < m.n; ++p)
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c <= a; ++c) trip.emplace_back(3 * p + a, 3 * p + c, 1.0);
  for (int f = 0; f < m.nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int g = TT(f, k);
      if (g < 0) continue;
      Impl::Slot s{f, k, g, false, {}};
      s.pos.fill(-1);
      const int pf = m.unknown[f], pg = m.unknown[g];
      if (pf >= 0) m.diag_count[pf] += 1;
      if (pg >= 0) m.diag_count[pg] += 1;
      if (pf >= 0 && pg >= 0) {
        s.f_high = pf > pg;
        const int hi = std::max(pf, pg), lo = std::min(pf, pg);
        for (int a = 0; a < 3; ++a)
          for (int c = 0; c < 3; ++c) trip.emplace_back(3 * hi + a, 3 * lo + c, 1.0);
      }
      m.slots.push_back(s);
    }
  m.pattern.resize(3 * m.n, 3 * m.n);
  m.pattern.setFromTriplets(trip.begin(), trip.end());
  m.pattern.makeCompressed();
  auto position = [&](int row, int col) {
    const int* inner = m.pattern.innerIndexPtr();
    const int b = m.pattern.outerIndexPtr()[col], e = m.pattern.outerIndexPtr()[col + 1];
    const int* it = std::lower_bound(inner + b, inner + e, row);
    if (it == inner + e || *it != row) throw NumericalError("fit: rotation-system pattern is inconsistent");
    return static_cast<int>(it - inner);
  };
  for (auto& s : m.slots) {
    const int pf = m.unknown[s.f], pg = m.unknown[s.g];
    if (pf < 0 || pg < 0) continue;
    const int hi = std::max(pf, pg), lo = std::min(pf, pg);
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) s.pos[3 * a + c] = position(3 * hi + a, 3 * lo + c);
  }
  m.diag_pos.resize(m.n);
  for (int p = 0; p < m.n; ++p)
    for (int a = 0; a < 3; ++a)
      for (int c = 0; c < 3; ++c) m.diag_pos[p][3 * a + c] = c <= a ? position(3 * p + a, 3 * p + c) : -1;
  m.referenced.assign(m.nv, 0);
  for (int f = 0; f < m.nf; ++f)
    for (int k = 0; k < 3; ++k) m.referenced[F(f, k)] = 1;
  m.identity.assign(m.nf, Eigen::Matrix3d::Identity());
  (void)F;
}

ModelFitter::~ModelFitter() = default;

Eigen::VectorXd ModelFitter::project(const Eigen::MatrixX3d& V, int K) const {
  if (K < 1 || K > pca_.component_count())
    throw InputError(fmt::format("fit: {} components requested, the model has {}", K, pca_.component_count()));
  const Encoding e = encode(*tmpl_, V, mean_);
  return pca_.basis.leftCols(K).transpose() * (e.values - pca_.mean);
}

Eigen::MatrixX3d ModelFitter::evaluate(const Eigen::VectorXd& c, Eigen::MatrixXd* J) const {
  Workspace ws;
  Eigen::MatrixX3d V = solve(ws, c);
  if (J) jacobian(ws, static_cast<int>(c.size()), *J);
  return V;
}

Eigen::MatrixX3d ModelFitter::solve(Workspace& ws, const Eigen::VectorXd& c) const {
  const Impl& m = *impl_;
  const int K = static_cast<int>(c.size());
  if (K > pca_.component_count())
    throw InputError(fmt::format("fit: {} coefficients given, the model has {} components", K, pca_.component_count()));
  ws.x = pca_.mean + pca_.basis.leftCols(K) * c;
  const Eigen::VectorXd& x = ws.x;
  Impl::State& st = ws.state;
  encoding_matrices(Encoding{x, mean_}, st.slot_R, st.S);

  // Rotation system N X = b (the decoder's, docs/method.md §3.4).
  SparseMatrixd N = m.pattern;
  double* val = N.valuePtr();
  std::fill(val, val + N.nonZeros(), 0.0);
  for (int p = 0; p < m.n; ++p)
    for (int a = 0; a < 3; ++a) val[m.diag_pos[p][3 * a + a]] = m.diag_count[p];
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(3 * m.n, 3);
  for (const auto& s : m.slots) {
    const Eigen::Matrix3d& Rs = st.slot_R[3 * s.f + s.k];
    const int pf = m.unknown[s.f], pg = m.unknown[s.g];
    if (pf >= 0 && pg >= 0) {
      // Block (f, g) gets −R̂; stored lower: as is when f is the higher index, else transposed.
      for (int a = 0; a < 3; ++a)
        for (int cc = 0; cc < 3; ++cc) val[s.pos[3 * a + cc]] -= s.f_high ? Rs(a, cc) : Rs(cc, a);
    } else if (pf < 0 && pg >= 0) {
      b.middleRows<3>(3 * pg) += Rs.transpose();  // X_f = I (fixed)
    } else if (pg < 0 && pf >= 0) {
      b.middleRows<3>(3 * pf) += Rs;              // X_g = I (fixed)
    }
  }
  if (!ws.chol) {
    ws.chol = std::make_unique<Cholesky>();
    ws.chol->analyzePattern(N);
  }
  Cholesky& chol = *ws.chol;
  chol.factorize(N);
  if (chol.info() != Eigen::Success) throw NumericalError("fit: the rotation system is not positive definite");
  st.X = chol.solve(b);
  if (!st.X.allFinite()) throw NumericalError("fit: the rotation solve produced NaN");
  st.R.assign(m.nf, Eigen::Matrix3d::Identity());
  st.Pinv.assign(m.nf, Eigen::Matrix3d::Zero());
  tbb::parallel_for(0, m.nf, [&](int f) {
    const int p = m.unknown[f];
    if (p < 0) return;
    const Eigen::Matrix3d M = st.X.middleRows<3>(3 * p).transpose();
    st.R[f] = closest_rotation(M);
    Eigen::Matrix3d P = st.R[f].transpose() * M;
    P = 0.5 * (P + P.transpose()).eval();
    st.Pinv[f] = (P.trace() * Eigen::Matrix3d::Identity() - P).inverse();
  });
  return decoder_.solve_positions(st.R, st.S);
}

// Forward-mode derivative of the decoded vertices w.r.t. the first K coefficients at the state
// of the last solve() (see the header).
void ModelFitter::jacobian(Workspace& ws, int K, Eigen::MatrixXd& Jout) const {
  const Impl& m = *impl_;
  const Impl::State& st = ws.state;
  const Eigen::VectorXd& x = ws.x;
  Cholesky& chol = *ws.chol;
  Eigen::MatrixXd* J = &Jout;
  // In chunks of coefficients (memory: 3n × 3·chunk doubles).
  J->resize(3 * m.nv, K);
  std::vector<Eigen::Matrix3d> Jr(m.slots.size());
  tbb::parallel_for(0, static_cast<int>(m.slots.size()), [&](int i) {
    const auto& s = m.slots[i];
    Jr[i] = right_jacobian(x.segment<3>(15 * s.f + 3 * s.k));
  });
  auto X_of = [&](int f) -> Eigen::Matrix3d {
    const int p = m.unknown[f];
    return p < 0 ? Eigen::Matrix3d::Identity() : Eigen::Matrix3d(st.X.middleRows<3>(3 * p));
  };
  const int chunk = 32;
  for (int k0 = 0; k0 < K; k0 += chunk) {
    const int kc = std::min(chunk, K - k0);
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(3 * m.n, 3 * kc);
    tbb::parallel_for(0, kc, [&](int j) {
      const Eigen::Ref<const Eigen::VectorXd> bk = pca_.basis.col(k0 + j);
      auto out = rhs.middleCols<3>(3 * j);
      for (size_t i = 0; i < m.slots.size(); ++i) {
        const auto& s = m.slots[i];
        const Eigen::Vector3d w = Jr[i] * bk.segment<3>(15 * s.f + 3 * s.k);
        if (w.squaredNorm() == 0) continue;
        const Eigen::Matrix3d dR = st.slot_R[3 * s.f + s.k] * skew(w);
        const int pf = m.unknown[s.f], pg = m.unknown[s.g];
        if (pg >= 0) out.middleRows<3>(3 * pg) += dR.transpose() * X_of(s.f);
        if (pf >= 0) out.middleRows<3>(3 * pf) += dR * X_of(s.g);
      }
    });
    const Eigen::MatrixXd dX = chol.solve(rhs);
    tbb::parallel_for(0, kc, [&](int j) {
      const Eigen::Ref<const Eigen::VectorXd> bk = pca_.basis.col(k0 + j);
      std::vector<Eigen::Matrix3d> dU(m.nf);
      for (int f = 0; f < m.nf; ++f) {
        const Eigen::Matrix3d dS = stretch_of(bk.data() + 15 * f + 9);
        const int p = m.unknown[f];
        Eigen::Matrix3d dR = Eigen::Matrix3d::Zero();
        if (p >= 0) {
          const Eigen::Matrix3d dM = dX.block<3, 3>(3 * p, 3 * j).transpose();
          const Eigen::Matrix3d W = st.R[f].transpose() * dM - dM.transpose() * st.R[f];
          dR = st.R[f] * skew(st.Pinv[f] * axial(W));
        }
        dU[f] = dR * st.S[f] + st.R[f] * dS;
      }
      Eigen::MatrixX3d dV = decoder_.solve_positions(dU, m.identity);
      for (int v = 0; v < m.nv; ++v) {
        if (!m.referenced[v]) dV.row(v).setZero();
        J->block<3, 1>(3 * v, k0 + j) = dV.row(v).transpose();
      }
    });
  }
}

ModelFit ModelFitter::fit(const Eigen::MatrixX3d& Y, const ModelFitOptions& o,
                          const ProgressCallback& progress) const {
  o.validate();
  const auto t_start = Clock::now();
  const Impl& m = *impl_;
  if (Y.rows() != m.nv)
    throw InputError(fmt::format("fit: the mesh has {} vertices, the model's template has {}", Y.rows(), m.nv));
  if (!Y.allFinite()) throw InputError("fit: the mesh has NaN or infinite coordinates");
  const int K = o.components < 0 ? pca_.component_count() : o.components;
  if (K > pca_.component_count())
    throw InputError(fmt::format("fit: {} components requested, the model has {}", K, pca_.component_count()));
  if (o.start.size() > K)
    throw InputError(fmt::format("fit: a start of {} coefficients for a fit of {} components", o.start.size(), K));
  ModelFit out;
  out.summary.components = K;
  Eigen::VectorXd c = Eigen::VectorXd::Zero(K);
  if (o.start.size() > 0)
    c.head(o.start.size()) = o.start;
  else if (o.start_from_projection)
    c = project(Y, K);
  Eigen::VectorXd inv_lambda = Eigen::VectorXd::Zero(K);
  for (int k = 0; k < K; ++k)
    if (pca_.eigenvalues(k) > 0) inv_lambda(k) = 1.0 / pca_.eigenvalues(k);

  // An evaluation: decoded (solver gauge) and rigidly placed vertices, cost.
  struct Eval {
    Eigen::MatrixX3d raw, placed;
    RigidMotion rigid;
    double cost = 0;
  };
  Workspace ws;
  auto evaluate_at = [&](const Eigen::VectorXd& cc) {
    Eval e;
    const auto t0 = Clock::now();
    e.raw = solve(ws, cc);
    out.summary.decode_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
    e.rigid = fit_rigid_motion(e.raw, Y);
    e.placed = apply(e.rigid, e.raw);
    e.cost = (e.placed - Y).squaredNorm() +
             o.prior_weight * (cc.array().square() * inv_lambda.head(cc.size()).array()).sum();
    ++out.summary.evaluations;
    return e;
  };
  Eval cur = evaluate_at(c);
  bool factor_is_current = true;  // ws holds cur's state
  out.summary.start_mean_mm = (cur.placed - Y).rowwise().norm().mean();
  out.summary.history_mean_mm.push_back(out.summary.start_mean_mm);

  // Levenberg–Marquardt on the first Kc components; the continuation stage (Kc < K, looser
  // tolerance) brings a far start close at a fraction of the Jacobian's cost, which is
  // linear in the number of components.
  auto run = [&](int Kc, double tolerance, int max_iterations) {
    double mu = 1e-4;
    const int P = Kc + 6;
    Eigen::MatrixXd Jraw;
    // Steps since Jraw was computed (−1: none yet, or it must be recomputed).
    int age = -1;
    for (int it = 0; it < max_iterations; ++it) {
      report_progress(progress, std::min(0.99, static_cast<double>(out.summary.iterations) / std::max(1, o.max_iterations)),
                      fmt::format("iteration {} ({} components)", out.summary.iterations + 1, Kc));
      const bool fresh = age < 0 || age >= o.jacobian_reuse;
      if (fresh) {
        if (!factor_is_current) {
          cur = evaluate_at(c);
          factor_is_current = true;
        }
        const auto t0 = Clock::now();
        jacobian(ws, Kc, Jraw);
        out.summary.jacobian_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
        ++out.summary.jacobians;
        age = 0;
      } else {
        ++age;
      }
      ++out.summary.iterations;
      // Jacobian in the target's frame: [Q·dv/dc | rotation about the centroid | translation].
      const Eigen::Matrix3d& Q = cur.rigid.R;
      const Eigen::RowVector3d centroid = cur.placed.colwise().mean();
      Eigen::MatrixXd H = Eigen::MatrixXd::Zero(P, P);
      Eigen::VectorXd g;
      {
        Eigen::MatrixXd Jt(3 * m.nv, P);
        tbb::parallel_for(0, m.nv, [&](int v) {
          Jt.block(3 * v, 0, 3, Kc) = Q * Jraw.block(3 * v, 0, 3, Kc);
          const Eigen::Vector3d p = (cur.placed.row(v) - centroid).transpose();
          Jt.block<3, 3>(3 * v, Kc) = -skew(p);
          Jt.block<3, 3>(3 * v, Kc + 3).setIdentity();
        });
        Eigen::VectorXd r(3 * m.nv);
        for (int v = 0; v < m.nv; ++v) r.segment<3>(3 * v) = (cur.placed.row(v) - Y.row(v)).transpose();
        H.selfadjointView<Eigen::Lower>().rankUpdate(Jt.transpose());
        H = H.selfadjointView<Eigen::Lower>();
        g = Jt.transpose() * r;
      }
      for (int k = 0; k < Kc; ++k) {
        H(k, k) += o.prior_weight * inv_lambda(k);
        g(k) += o.prior_weight * inv_lambda(k) * c(k);
      }
      bool accepted = false, done = false;
      // A chord step (stale Jacobian) gets one try: if it fails, the next step is a fresh one
      // rather than a more damped step along a stale model.
      for (int attempt = 0; attempt < (fresh ? 8 : 1) && !accepted; ++attempt) {
        Eigen::MatrixXd A = H;
        for (int i = 0; i < P; ++i) A(i, i) += mu * std::max(H(i, i), 1e-12);
        const Eigen::VectorXd step = A.ldlt().solve(-g);
        if (!step.allFinite()) {
          mu *= 10;
          continue;
        }
        Eigen::VectorXd c_new = c;
        c_new.head(Kc) += step.head(Kc);
        Eval next = evaluate_at(c_new);
        if (next.cost < cur.cost) {
          const double decrease = (cur.cost - next.cost) / std::max(cur.cost, 1e-300);
          const double moved = (next.placed - cur.placed).rowwise().norm().maxCoeff();
          c = c_new;
          cur = std::move(next);
          factor_is_current = true;
          mu = std::max(mu / 3, 1e-9);
          accepted = true;
          if (decrease < tolerance || moved < o.step_tolerance_mm) done = true;
        } else {
          factor_is_current = false;
          if (fresh) mu *= 4;
        }
      }
      out.summary.history_mean_mm.push_back((cur.placed - Y).rowwise().norm().mean());
      if (!fresh && (!accepted || done)) {
        age = -1;  // only a fresh Jacobian may fail or stop the fit
        continue;
      }
      if (!accepted) return true;  // no descent along the damped steps: a minimum (to tolerance)
      if (done) return true;
    }
    return false;
  };
  bool converged = o.max_iterations == 0;
  int budget = o.max_iterations;
  if (o.continuation_components > 0 && o.continuation_components < K && budget > 0) {
    run(o.continuation_components, o.continuation_tolerance, std::min(budget, o.continuation_iterations));
    budget -= out.summary.iterations;
  }
  if (budget > 0) converged = run(K, o.relative_tolerance, budget);
  out.coefficients = c;
  out.V = cur.placed;
  out.vertex_error = (cur.placed - Y).rowwise().norm();
  std::vector<double> e(out.vertex_error.data(), out.vertex_error.data() + out.vertex_error.size());
  out.summary.mean_mm = out.vertex_error.mean();
  out.summary.rms_mm = std::sqrt(out.vertex_error.squaredNorm() / std::max<Eigen::Index>(1, out.vertex_error.size()));
  out.summary.p95_mm = percentile(e, 95);
  out.summary.max_mm = out.vertex_error.maxCoeff();
  out.summary.converged = converged;
  out.summary.seconds = std::chrono::duration<double>(Clock::now() - t_start).count();
  report_progress(progress, 1.0, "done");
  return out;
}

}  // namespace bodymodel
