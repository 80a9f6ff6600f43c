#include "registration/hand_stage.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "core/geometry.h"
#include "core/point_index.h"

namespace bodymodel {

namespace {

// The parameters the hand stage fits: the late ones (finger curls, thumbs), with hand_wrists the
// wrists (the first fitted body bone above a late parameter) and with hand_forearm_twist the
// twist parameter right above each wrist (the forearm's).
struct HandParameters {
  std::vector<int> late;      // the late parameters
  std::vector<char> free;     // #P: fitted in the hand stage
  std::vector<int> wrist_of;  // #P: the wrist bone of each hand parameter, -1 for the others
  std::vector<int> fitted;    // the parameters with `free`, in order
};

HandParameters hand_parameters(const PoseProblem& p) {
  const int nfree = p.z.count();
  const auto& params = p.z.params;
  const auto& free_index = p.z.free_index;
  HandParameters hp;
  for (int k = 0; k < nfree; ++k)
    if (params[k].late) hp.late.push_back(k);
  hp.free.assign(nfree, 0);
  hp.wrist_of.assign(nfree, -1);
  auto fitted_above = [&](int b) {
    int a = p.skeleton.parents[b];
    while (a > 0 && free_index[a] < 0) a = p.skeleton.parents[a];
    return a;
  };
  for (int k : hp.late) {
    hp.free[k] = 1;
    int a = params[k].bones[0];
    do a = fitted_above(a);
    while (a > 0 && params[free_index[a]].late);
    hp.wrist_of[k] = std::max(a, 0);
    if (!p.o.hand_wrists || a <= 0) continue;
    hp.free[free_index[a]] = 1;
    hp.wrist_of[free_index[a]] = a;
    const int t = fitted_above(a);
    if (p.o.hand_forearm_twist && t > 0 && params[free_index[t]].twist) {
      hp.free[free_index[t]] = 1;
      hp.wrist_of[free_index[t]] = a;
    }
  }
  for (int k = 0; k < nfree; ++k)
    if (hp.free[k]) hp.fitted.push_back(k);
  return hp;
}

// The pairs of one hand-stage solve, both ways between the hand samples and the scan points of
// the hand.
struct HandPairs {
  std::vector<int> hand_points;  // scan points of the hand
  Eigen::MatrixX3d SV;           // #hand samples by 3: the posed hand samples (mm)
  std::vector<int> fwd;          // per hand sample: its scan point, -1 none
  std::vector<int> bwd;          // per bstride-th hand point: its hand sample, -1 none
  int bstride = 1;
};

class HandStage {
 public:
  HandStage(const PoseProblem& p, PoseUnknowns& u, PoseFitSummary& sum,
            const ProgressCallback& progress)
      : p_(p), o_(p.o), u_(u), sum_(sum), progress_(progress), hp_(hand_parameters(p)) {
    // Coupling groups: the curl parameters of one hand.
    for (int k : hp_.late)
      if (p_.z.params[k].curl) coupled_[p_.z.hand_of[p_.z.params[k].bones[0]]].push_back(k);
  }

  void run();

 private:
  void run_start(size_t s);
  void run_phases();
  bool find_pairs(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& VN, double dmax,
                  HandPairs& pairs) const;
  bool solve(int hiter, double coupling);
  void accept_per_parameter();
  void collect_compared_points(const Eigen::MatrixX3d& V, const std::vector<int>& hv, double cap,
                               std::vector<char>& in_set) const;
  double hand_cost(const std::vector<int>& hv, const std::vector<int>& set, double cap) const;
  void choose_starts(size_t nstarts);
  void record(size_t s);
  std::vector<int> compared_points(int h, size_t a, size_t b) const;
  double start_cost(int h, size_t s, const std::vector<int>& set) const;

  const PoseProblem& p_;
  const PoseFitOptions& o_;
  PoseUnknowns& u_;
  PoseFitSummary& sum_;
  const ProgressCallback& progress_;
  const HandParameters hp_;
  std::map<int, std::vector<int>> coupled_;  // wrist bone → its curl parameters
  // The joints where the last phase started (the per-parameter acceptance reverts to them) and
  // where the body stage left them (every start begins there).
  std::vector<Eigen::Vector3d> hand_start_, body_joints_;
  // Start comparison (several starts): per hand, its wrist bone; per hand-region vertex, its hand
  // (index into hands_, -1 none); per result (the starts, then the body stage's hand), the
  // joints, the posed template and, per scan point, the hand of its closest template vertex
  // within cap_ (-1 none).
  std::vector<int> hands_, vertex_hand_;
  double cap_ = 30.0;
  std::vector<std::vector<Eigen::Vector3d>> results_;
  std::vector<Eigen::MatrixX3d> Vs_;
  std::vector<std::vector<int>> near_hand_;
};

void HandStage::run() {
  if (hp_.late.empty() || p_.hand_samples.empty() || o_.hand_iterations <= 0) return;
  body_joints_ = u_.joints;
  hand_start_ = u_.joints;
  const size_t nstarts = std::max<size_t>(1, o_.hand_start_curls_deg.size());
  if (nstarts == 1)
    run_start(0);
  else
    choose_starts(nstarts);
}

// One start s (PoseFitOptions::hand_start_curls_deg and the tucks and twists): the joints from
// the body stage with the start's curls, tucks and added forearm twists, then the phases.
void HandStage::run_start(size_t s) {
  u_.joints = body_joints_;
  if (!o_.hand_start_curls_deg.empty())
    for (int k : hp_.fitted) {
      const FittedParameter& prm = p_.z.params[k];
      if (prm.curl) u_.joints[k][0] = o_.hand_start_curls_deg[s] * M_PI / 180.0;
      if (prm.tuck)
        u_.joints[k][0] =
            s < o_.hand_start_tucks_deg.size() ? o_.hand_start_tucks_deg[s] * M_PI / 180.0 : 0.0;
      if (!prm.late && prm.twist && s < o_.hand_start_twists_deg.size())
        u_.joints[k][0] += o_.hand_start_twists_deg[s] * M_PI / 180.0;
    }
  run_phases();
}

// The phases from the current joints: first (tied_hand_phase) each hand's fingers curl as one, a
// grasp, then each on its own, started there; then the per-parameter acceptance.
void HandStage::run_phases() {
  const int run_first_iteration = sum_.hand_iterations;
  const int phases = o_.tied_hand_phase ? 2 : 1;
  for (int phase = 0; phase < phases; ++phase) {
    const double coupling = phase + 1 < phases ? 1e8 : o_.finger_coupling;
    hand_start_ = u_.joints;
    for (int hiter = 0; hiter < o_.hand_iterations; ++hiter)
      if (!solve(hiter, coupling)) break;
  }
  if (o_.hand_accept_cap > 0 && sum_.hand_iterations > run_first_iteration) accept_per_parameter();
}

// The pairs of the hand samples with the scan points of the hand: those within dmax of the posed
// hand's box whose closest posed template vertex is in the hand region. False with fewer than ten
// such points.
bool HandStage::find_pairs(const Eigen::MatrixX3d& V, const Eigen::MatrixX3d& VN, double dmax,
                           HandPairs& pairs) const {
  const PointCloud& scan = p_.scan;
  const int nh = int(p_.hand_samples.size());
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (int i = 0; i < p_.vertex_count; ++i)
    if (p_.hand_region[i]) {
      lo = lo.cwiseMin(V.row(i).transpose());
      hi = hi.cwiseMax(V.row(i).transpose());
    }
  lo.array() -= dmax;
  hi.array() += dmax;
  PointIndex vertex_index(V);
  std::vector<int> cand;
  for (Eigen::Index j = 0; j < scan.P.rows(); ++j) {
    const Eigen::Vector3d q = scan.P.row(j).transpose();
    if ((q.array() >= lo.array()).all() && (q.array() <= hi.array()).all()) cand.push_back(int(j));
  }
  std::vector<char> is_hand(cand.size(), 0);
  tbb::parallel_for(0, int(cand.size()), [&](int c) {
    const int i = vertex_index.nearest(scan.P.row(cand[c]).transpose());
    is_hand[c] = i >= 0 && p_.hand_region[i];
  });
  std::vector<int>& hand_points = pairs.hand_points;
  for (size_t c = 0; c < cand.size(); ++c)
    if (is_hand[c]) hand_points.push_back(cand[c]);
  if (hand_points.size() < 10) return false;
  Eigen::MatrixX3d HP(hand_points.size(), 3);
  for (size_t c = 0; c < hand_points.size(); ++c) HP.row(c) = scan.P.row(hand_points[c]);
  PointIndex hand_index(HP);
  pairs.SV.resize(nh, 3);
  for (int h = 0; h < nh; ++h) pairs.SV.row(h) = V.row(p_.hand_samples[h]);
  PointIndex sample_index(pairs.SV);
  auto normal_ok = [&](int j, int i) {
    if (!scan.has_normals()) return true;
    return p_.normal_agreement(j, VN.row(i)) >= p_.cos_min;
  };
  pairs.fwd.assign(nh, -1);
  tbb::parallel_for(0, nh, [&](int h) {
    double d2 = 0;
    const int c = hand_index.nearest(pairs.SV.row(h).transpose(), &d2);
    if (c >= 0 && d2 <= dmax * dmax && normal_ok(hand_points[c], p_.hand_samples[h]))
      pairs.fwd[h] = hand_points[c];
  });
  const int hp = int(hand_points.size());
  pairs.bstride = std::max(1, hp / std::max(1, nh));
  pairs.bwd.assign((hp + pairs.bstride - 1) / pairs.bstride, -1);
  tbb::parallel_for(0, int(pairs.bwd.size()), [&](int k) {
    const int j = hand_points[k * pairs.bstride];
    double d2 = 0;
    const int h = sample_index.nearest(scan.P.row(j).transpose(), &d2);
    if (h >= 0 && d2 <= dmax * dmax && normal_ok(j, p_.hand_samples[h])) pairs.bwd[k] = h;
  });
  return true;
}

// One solve of the hand parameters (iteration hiter; `coupling`: weight of each finger's pull
// towards its hand's mean curl). False when the iterations stop: too few pairs, or converged.
bool HandStage::solve(int hiter, double coupling) {
  const PointCloud& scan = p_.scan;
  const auto& params = p_.z.params;
  const int nh = int(p_.hand_samples.size());
  report_progress(progress_, 0.95, "pose fit: hands");
  const Eigen::MatrixX3d V = posed_template(p_, u_);
  const Eigen::MatrixX3d VN = vertex_normals(V, p_.tpl.F);
  const double dmax = std::max(o_.hand_max_distance,
                               o_.hand_initial_max_distance * std::pow(0.5, hiter));
  HandPairs pairs;
  if (!find_pairs(V, VN, dmax, pairs)) return false;
  ceres::Problem problem;
  add_parameter_blocks(problem, p_, u_);
  problem.SetParameterBlockConstant(&u_.scale);
  problem.SetParameterBlockConstant(u_.root.data());
  problem.SetParameterBlockConstant(u_.translation.data());
  for (int k = 0; k < p_.z.count(); ++k)
    if (!hp_.free[k] || params[k].tuck) problem.SetParameterBlockConstant(u_.joints[k].data());
  if (o_.curl_max_deg > o_.curl_min_deg)
    for (int k : hp_.fitted)
      if (params[k].curl) {
        u_.joints[k][0] = std::clamp(u_.joints[k][0], o_.curl_min_deg * M_PI / 180.0,
                                     o_.curl_max_deg * M_PI / 180.0);
        problem.SetParameterLowerBound(u_.joints[k].data(), 0, o_.curl_min_deg * M_PI / 180.0);
        problem.SetParameterUpperBound(u_.joints[k].data(), 0, o_.curl_max_deg * M_PI / 180.0);
      }
  int matched = 0;
  double d2sum = 0;
  for (int h = 0; h < nh; ++h) {
    if (pairs.fwd[h] < 0) continue;
    const Eigen::Vector3d target = scan.P.row(pairs.fwd[h]).transpose();
    d2sum += (pairs.SV.row(h).transpose() - target).squaredNorm();
    ++matched;
    const Eigen::Vector3d normal =
        scan.has_normals() ? Eigen::Vector3d(scan.N.row(pairs.fwd[h])) : Eigen::Vector3d::Zero();
    add_sample(problem, p_, u_, p_.hand_first + h, target, normal, 1.0, 1.0,
               o_.point_to_point_weight, new ceres::HuberLoss(o_.robust_scale));
  }
  int nback = 0;
  for (int b : pairs.bwd) nback += b >= 0;
  if (nback > 0) {
    const double w = std::sqrt(double(std::max(matched, 1)) / nback);
    for (size_t k = 0; k < pairs.bwd.size(); ++k) {
      if (pairs.bwd[k] < 0) continue;
      const int j = pairs.hand_points[k * pairs.bstride];
      const Eigen::Vector3d normal =
          scan.has_normals() ? Eigen::Vector3d(scan.N.row(j)) : Eigen::Vector3d::Zero();
      add_sample(problem, p_, u_, p_.hand_first + pairs.bwd[k], scan.P.row(j).transpose(), normal,
                 w, 1.0, o_.point_to_point_weight, new ceres::HuberLoss(o_.robust_scale));
    }
  }
  if (matched + nback < 10) return false;
  for (size_t k = 0; k < p_.landmarks.size(); ++k)
    if (!p_.landmark_in_body[k])
      add_sample(problem, p_, u_, p_.body_samples + int(k), p_.landmarks[k].target,
                 Eigen::Vector3d::Zero(), o_.landmark_weight * std::sqrt(double(nh) / 100.0), 0.0,
                 1.0, nullptr);
  for (int k : hp_.fitted) {
    if (params[k].tuck) continue;  // held where the start put it
    const double w = std::sqrt(o_.pose_prior * params[k].prior * double(params[k].bones.size()));
    add_joint_prior(problem, params[k].one_dof(), w, Eigen::Vector3d::Zero(), u_.joints[k]);
    // The wrists' twist (a ball joint's rotation about its bone).
    if (o_.wrist_twist_prior > 0 && !params[k].late && !params[k].one_dof())
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<AxisPriorResidual, 1, 3>(new AxisPriorResidual{
              std::sqrt(o_.wrist_twist_prior * double(params[k].bones.size())),
              p_.z.bone_axis[params[k].bones[0]]}),
          nullptr, u_.joints[k].data());
  }
  // Each finger's curl towards its hand's mean curl (the mean a free variable).
  std::vector<double> means;
  means.reserve(coupled_.size());
  if (coupling > 0)
    for (const auto& [wrist, ks] : coupled_) {
      if (ks.size() < 2) continue;
      double m = 0;
      for (int k : ks) m += u_.joints[k][0];
      means.push_back(m / ks.size());
      for (int k : ks)
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<CouplingResidual, 1, 1, 1>(new CouplingResidual{
                std::sqrt(coupling * double(params[k].bones.size()))}),
            nullptr, u_.joints[k].data(), &means.back());
    }
  const std::vector<Eigen::Vector3d> old = u_.joints;
  solve_pose_problem(problem, o_.solver_iterations, o_.threads);
  ++sum_.hand_iterations;
  sum_.hand_rms = matched ? std::sqrt(d2sum / matched) : 0.0;
  double max_deg = 0;
  for (int k : hp_.fitted)
    max_deg = std::max(max_deg, (u_.joints[k] - old[k]).norm() * 180.0 / M_PI);
  return !(dmax <= o_.hand_max_distance && max_deg < o_.convergence_deg);
}

// Marks in in_set the scan points (within cap of the box of the hand vertices hv of V) whose
// closest vertex of the posed template V is in the hand region, within cap.
void HandStage::collect_compared_points(const Eigen::MatrixX3d& V, const std::vector<int>& hv,
                                        double cap, std::vector<char>& in_set) const {
  const PointCloud& scan = p_.scan;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (int i : hv) {
    lo = lo.cwiseMin(V.row(i).transpose());
    hi = hi.cwiseMax(V.row(i).transpose());
  }
  lo.array() -= cap;
  hi.array() += cap;
  PointIndex vertex_index(V);
  tbb::parallel_for(0, int(scan.P.rows()), [&](int j) {
    const Eigen::Vector3d q = scan.P.row(j).transpose();
    if (!((q.array() >= lo.array()).all() && (q.array() <= hi.array()).all())) return;
    double d2 = 0;
    const int i = vertex_index.nearest(q, &d2);
    if (i >= 0 && p_.hand_region[i] && d2 <= cap * cap) in_set[j] = 1;
  });
}

// Two-sided distance of the hand (vertices hv, posed with the current unknowns) and the scan
// points `set`, each distance capped at cap (mm).
double HandStage::hand_cost(const std::vector<int>& hv, const std::vector<int>& set,
                            double cap) const {
  const PointCloud& scan = p_.scan;
  const Eigen::MatrixX3d V = posed_template(p_, u_);
  Eigen::MatrixX3d H(hv.size(), 3);
  for (size_t c = 0; c < hv.size(); ++c) H.row(c) = V.row(hv[c]);
  PointIndex hand_index(H);
  std::vector<double> a(set.size()), b(hv.size());
  tbb::parallel_for(0, int(set.size()), [&](int c) {
    double d2 = 0;
    hand_index.nearest(scan.P.row(set[c]).transpose(), &d2);
    a[c] = std::min(std::sqrt(d2), cap);
  });
  tbb::parallel_for(0, int(hv.size()), [&](int c) {
    double d2 = 0;
    p_.scan_index.nearest(H.row(c).transpose(), &d2);
    b[c] = std::min(std::sqrt(d2), cap);
  });
  double sa = 0, sb = 0;
  for (double x : a) sa += x;
  for (double x : b) sb += x;
  return 0.5 * (sa / std::max<size_t>(1, a.size()) + sb / std::max<size_t>(1, b.size()));
}

// Per-parameter acceptance (docs/pose_fit.md#hand-acceptance): each hand parameter keeps its
// fitted value only if that lowers the hand's two-sided distance to the scan, compared on the
// scan points of the hand in the start or the fitted pose; else it goes back to where the last
// phase started it.
void HandStage::accept_per_parameter() {
  std::vector<int> hv;
  for (int i = 0; i < p_.vertex_count; ++i)
    if (p_.hand_region[i]) hv.push_back(i);
  const double cap = o_.hand_accept_cap;
  std::vector<char> in_set(p_.scan.P.rows(), 0);
  const std::vector<Eigen::Vector3d> fitted = u_.joints;
  for (int k : hp_.fitted) u_.joints[k] = hand_start_[k];
  collect_compared_points(posed_template(p_, u_), hv, cap, in_set);
  u_.joints = fitted;
  collect_compared_points(posed_template(p_, u_), hv, cap, in_set);
  std::vector<int> set;
  for (Eigen::Index j = 0; j < p_.scan.P.rows(); ++j)
    if (in_set[j]) set.push_back(int(j));
  double best = hand_cost(hv, set, cap);
  sum_.hand_accept_before = best;
  for (int k : hp_.fitted) {
    if (u_.joints[k] == hand_start_[k]) continue;
    const Eigen::Vector3d keep = u_.joints[k];
    u_.joints[k] = hand_start_[k];
    const double c = hand_cost(hv, set, cap);
    if (c < best) {
      best = c;
      ++sum_.hand_reverted;
    } else {
      u_.joints[k] = keep;
    }
  }
  sum_.hand_accept_after = best;
}

// Keeps result s: its joints, posed template and each scan point's hand.
void HandStage::record(size_t s) {
  const PointCloud& scan = p_.scan;
  results_[s] = u_.joints;
  Vs_[s] = posed_template(p_, u_);
  near_hand_[s].assign(scan.P.rows(), -1);
  PointIndex vertex_index(Vs_[s]);
  tbb::parallel_for(0, int(scan.P.rows()), [&](int j) {
    double d2 = 0;
    const int i = vertex_index.nearest(scan.P.row(j).transpose(), &d2);
    if (i >= 0 && vertex_hand_[i] >= 0 && d2 <= cap_ * cap_) near_hand_[s][j] = vertex_hand_[i];
  });
}

// The scan points compared for hand h between results a and b: those whose closest template
// vertex (within cap) is on hand h in a, or, where none is on a hand in a, in b.
std::vector<int> HandStage::compared_points(int h, size_t a, size_t b) const {
  std::vector<int> set;
  for (Eigen::Index j = 0; j < p_.scan.P.rows(); ++j) {
    const int first = near_hand_[a][j] >= 0 ? near_hand_[a][j] : near_hand_[b][j];
    if (first == h) set.push_back(int(j));
  }
  return set;
}

// Two-sided distance of hand h in result s against the scan points `set`, after the translation
// that best aligns it (hand_start_align_steps alternating closest-point steps); NaN for an empty
// hand or set.
double HandStage::start_cost(int h, size_t s, const std::vector<int>& set) const {
  const PointCloud& scan = p_.scan;
  std::vector<int> hv;
  for (int i = 0; i < p_.vertex_count; ++i)
    if (vertex_hand_[i] == h) hv.push_back(i);
  if (hv.empty() || set.empty()) return std::numeric_limits<double>::quiet_NaN();
  Eigen::MatrixX3d H(hv.size(), 3);
  for (size_t c = 0; c < hv.size(); ++c) H.row(c) = Vs_[s].row(hv[c]);
  PointIndex hand_index(H);
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  double sa = 0, sb = 0;
  for (int step = 0; step <= o_.hand_start_align_steps; ++step) {
    sa = sb = 0;
    Eigen::Vector3d shift = Eigen::Vector3d::Zero();
    int pairs = 0;
    for (int j : set) {
      double d2 = 0;
      const Eigen::Vector3d q = scan.P.row(j).transpose();
      const int i = hand_index.nearest(q - t, &d2);
      const double d = std::sqrt(d2);
      sa += std::min(d, cap_);
      if (i >= 0 && d < cap_) shift += q - (H.row(i).transpose() + t), ++pairs;
    }
    for (int i = 0; i < H.rows(); ++i) {
      double d2 = 0;
      const Eigen::Vector3d v = H.row(i).transpose() + t;
      const int j = p_.scan_index.nearest(v, &d2);
      const double d = std::sqrt(d2);
      sb += std::min(d, cap_);
      if (j >= 0 && d < cap_) shift += scan.P.row(j).transpose() - v, ++pairs;
    }
    if (pairs > 0) t += shift / pairs;
  }
  return 0.5 * (sa / set.size() + sb / H.rows());
}

// Several starts (docs/pose_fit.md#hand-starts): per hand, each start in turn challenges the best
// so far on the scan points of that hand in either result; a later start must beat the first
// (open) one by hand_start_margin. A start with an earlier start's curl is that start's variant:
// it challenges only that start, once it is the best, and is not run if no hand kept it. Last,
// with hand_compare_body_stage, the body stage's hand challenges each hand's choice (margin 0).
void HandStage::choose_starts(size_t nstarts) {
  const Skeleton& skeleton = p_.skeleton;
  const auto& params = p_.z.params;
  // The hand of each hand parameter (its wrist) and of each hand-region vertex (its heaviest
  // bone's hand).
  const std::vector<int>& hand_id = hp_.wrist_of;
  std::vector<char> is_hand_bone(p_.bone_count, 0);
  for (int k : hp_.fitted) is_hand_bone[hand_id[k]] = 1;
  for (int b = 0; b < p_.bone_count; ++b)
    if (is_hand_bone[b]) hands_.push_back(b);
  vertex_hand_.assign(p_.vertex_count, -1);
  for (int i = 0; i < p_.vertex_count; ++i) {
    if (!p_.hand_region[i]) continue;
    int b = -1;
    double best = 0;
    for (SkinWeights::InnerIterator it(p_.W, i); it; ++it)
      if (it.value() > best) best = it.value(), b = int(it.col());
    for (; b >= 0; b = skeleton.parents[b])
      if (is_hand_bone[b]) {
        vertex_hand_[i] = int(std::find(hands_.begin(), hands_.end(), b) - hands_.begin());
        break;
      }
  }
  cap_ = o_.hand_accept_cap > 0 ? o_.hand_accept_cap : 30.0;
  const int nhands = int(hands_.size());
  results_.assign(nstarts + 1, {});  // slot nstarts: the body stage's hand
  Vs_.assign(nstarts + 1, {});
  near_hand_.assign(nstarts + 1, {});
  auto curl_of = [&](size_t s) {
    return s < o_.hand_start_curls_deg.size() ? o_.hand_start_curls_deg[s] : 0.0;
  };
  std::vector<int> choice(nhands, 0);
  for (size_t s = 0; s < nstarts; ++s) {
    size_t base = s;
    for (size_t e = 0; e < s && base == s; ++e)
      if (curl_of(e) == curl_of(s)) base = e;
    if (base != s && std::find(choice.begin(), choice.end(), int(base)) == choice.end()) continue;
    // A twisted start without a refitted forearm twist would repeat its base start.
    if (s < o_.hand_start_twists_deg.size() && o_.hand_start_twists_deg[s] != 0.0 &&
        std::none_of(hp_.fitted.begin(), hp_.fitted.end(),
                     [&](int k) { return !params[k].late && params[k].twist; }))
      continue;
    run_start(s);
    record(s);
    if (s == 0) continue;
    for (int h = 0; h < nhands; ++h) {
      const size_t w = size_t(choice[h]);
      if (base != s && base != w) continue;
      const std::vector<int> set = compared_points(h, w, s);
      const double cw = start_cost(h, w, set), cs = start_cost(h, s, set);
      if (!(cs == cs) || !(cw == cw)) continue;
      sum_.hand_start_comparisons.push_back({h, int(w), int(s), cw, cs});
      const double compared_w = w == 0 ? cw : cw / (1.0 - o_.hand_start_margin);
      if (cs / (1.0 - o_.hand_start_margin) < compared_w) choice[h] = int(s);
    }
  }
  if (o_.hand_compare_body_stage) {
    u_.joints = body_joints_;
    record(nstarts);
    for (int h = 0; h < nhands; ++h) {
      const size_t w = size_t(choice[h]);
      const std::vector<int> set = compared_points(h, w, nstarts);
      const double cw = start_cost(h, w, set), cb = start_cost(h, nstarts, set);
      if (!(cw == cw) || !(cb == cb)) continue;
      sum_.hand_start_comparisons.push_back({h, int(w), int(nstarts), cw, cb});
      if (cb <= cw) choice[h] = int(nstarts);
    }
  }
  u_.joints = results_[0];
  for (int k : hp_.fitted) {
    const int h = int(std::find(hands_.begin(), hands_.end(), hand_id[k]) - hands_.begin());
    u_.joints[k] = results_[choice[h]][k];
  }
  for (int h = 0; h < nhands; ++h) sum_.hand_start_choice.push_back(choice[h]);
}

}  // namespace

void run_hand_stage(const PoseProblem& problem, PoseUnknowns& unknowns, PoseFitSummary& summary,
                    const ProgressCallback& progress) {
  HandStage(problem, unknowns, summary, progress).run();
}

}  // namespace bodymodel
