#include "registration/pose_fit.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/geometry.h"
#include "core/point_index.h"

namespace bodymodel {

const std::vector<PoseParameter>& segment_pose_parameters() {
  static const std::vector<PoseParameter> params = [] {
    // One rotation per body segment. MakeHuman splits segments over several bones; left
    // independent, consecutive bones counter-rotate to absorb the subject's proportions at no
    // data cost (measured: joint error median 9.1° with every bone a free ball joint). So the
    // spine (spine04..01) and the neck (neck01..03) each bend as one (the same rotation on
    // every bone of the group), clavicle and shoulder01 move together, and the second bone of
    // each limb segment (upperarm02, lowerarm02, upperleg02, lowerleg02) only twists about its
    // own axis, as MakeHuman's poses use them. spine05 and pelvis.L/R stay at rest: they carry
    // almost no vertices of their own and duplicate the root's rotation.
    std::vector<PoseParameter> p = {{{"spine04", "spine03", "spine02", "spine01"}, false},
                                    {{"neck01", "neck02", "neck03"}, false},
                                    {{"head"}, false}};
    for (const char* side : {".L", ".R"}) {
      auto b = [&](const char* n) { return std::string(n) + side; };
      p.push_back({{b("clavicle"), b("shoulder01")}, false});
      p.push_back({{b("upperarm01")}, false});
      p.push_back({{b("upperarm02")}, true});
      p.push_back({{b("lowerarm01")}, false});
      p.push_back({{b("lowerarm02")}, true});
      p.push_back({{b("wrist")}, false});
      p.push_back({{b("upperleg01")}, false});
      p.push_back({{b("upperleg02")}, true});
      p.push_back({{b("lowerleg01")}, false});
      p.push_back({{b("lowerleg02")}, true});
      p.push_back({{b("foot")}, false});
      // Hands: scans show fists and open hands (a curled hand is ~1500 vertices 10–20 cm off).
      // One grasp rotation shared by the 12 phalanges of the four fingers, one for the thumb;
      // a weak prior, as the total curl of a fist is 3 × 70° per finger.
      std::vector<std::string> fingers;
      for (int f = 2; f <= 5; ++f)
        for (int k = 1; k <= 3; ++k) fingers.push_back(b(("finger" + std::to_string(f) + "-" + std::to_string(k)).c_str()));
      // Not anchored to the landmark-only pose: there the 100× prior keeps them open, and the
      // anchor (1e5 per bone) then held the fingers open against a fist. Unanchored, on the 15
      // database scans (pose only): flipped triangles 2216 → 557 (hands 1980 → 319; s008_p3's
      // fists 1612 → 196), correspondence p95 39.2 → 35.9 mm, joint median 6.47 → 6.48°.
      p.push_back({fingers, false, 0.1, false, false, false});
      p.push_back({{b("finger1-1"), b("finger1-2"), b("finger1-3")}, false, 0.3, false, false, false});
    }
    return p;
  }();
  return params;
}

std::vector<PoseParameter> with_hand_stage(const std::vector<PoseParameter>& parameters) {
  std::vector<PoseParameter> p;
  for (const auto& g : parameters)
    if (g.bones.empty() || g.bones[0].rfind("finger", 0) != 0) p.push_back(g);
  for (const char* side : {".L", ".R"}) {
    auto b = [&](const std::string& n) { return n + side; };
    // One curl angle per finger shared by its three phalanges (a fist is ~70° per phalanx),
    // the thumb a ball joint shared by its three bones; weak priors; hand stage only.
    for (int f = 2; f <= 5; ++f) {
      std::vector<std::string> finger;
      for (int k = 1; k <= 3; ++k)
        finger.push_back(b("finger" + std::to_string(f) + "-" + std::to_string(k)));
      p.push_back({finger, false, 0.1, true, true});
    }
    // The thumb: a ball joint at its base only (finger1-1; the other two phalanges at rest),
    // prior 1. Shared over its three bones (prior 0.3) it swung the whole thumb 38° off where
    // a scan (CMU 12_03) turned only the base: 15 database scans, pose only, hand flips 416 → 332,
    // distal phalanx median 16.4 → 14.5°.
    p.push_back({{b("finger1-1")}, false, 1.0, true, false});
    // The thumb's tuck across the palm (finger1-2, finger1-3), set by the hand stage's start
    // and never fitted: fitted freely (a ball joint there) it moved thumbs the scan does not
    // show, 15 database scans joint median 4.94 -> 5.04 deg.
    p.push_back({{b("finger1-2"), b("finger1-3")}, false, 1.0, true, false, false, true});
  }
  return p;
}

const std::vector<PoseParameter>& hand_stage_pose_parameters() {
  static const std::vector<PoseParameter> params = with_hand_stage(segment_pose_parameters());
  return params;
}

const std::vector<PoseParameter>& bone_pose_parameters() {
  static const std::vector<PoseParameter> params = [] {
    std::vector<PoseParameter> p;
    for (const auto& g : segment_pose_parameters()) {
      if (g.bones[0].rfind("finger", 0) == 0) {  // keep the grasp groups
        p.push_back(g);
        continue;
      }
      for (const auto& b : g.bones) p.push_back({{b}, false});
    }
    return p;
  }();
  return params;
}

const std::vector<PoseParameter>& default_pose_parameters() { return segment_pose_parameters(); }

const std::vector<std::string>& default_free_bones() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const auto& p : default_pose_parameters()) n.insert(n.end(), p.bones.begin(), p.bones.end());
    return n;
  }();
  return names;
}

Eigen::MatrixX3d pose_template(const Eigen::MatrixX3d& V_rest, const Skeleton& skeleton,
                               const SkinWeights& weights, double scale, const Pose& pose) {
  const Eigen::RowVector3d o = skeleton.heads.row(0);
  Skeleton s = skeleton;
  s.heads = ((skeleton.heads.rowwise() - o) * scale).rowwise() + o;
  s.tails = ((skeleton.tails.rowwise() - o) * scale).rowwise() + o;
  const Eigen::MatrixX3d V = ((V_rest.rowwise() - o) * scale).rowwise() + o;
  return linear_blend_skinning(V, weights, forward_kinematics(s, pose));
}

namespace {

// The kinematic chain a vertex depends on: its weighted bones and all their ancestors.
struct Chain {
  std::vector<int> bones;        // skeleton indices, parents before children (bones[0] = root)
  std::vector<int> parent;       // index into `bones` of the parent, -1 for the root
  std::vector<int> slot;         // parameter block of the bone's rotation (see below), -1 fixed
  std::vector<Eigen::Vector3d> twist_axis;   // unit rest axis of a twist-only bone, else zero
  std::vector<std::pair<int, double>> blend;  // (index into bones, weight)
  std::vector<std::vector<char>> below;       // below[e][a]: blend bone e is a or below it
};

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

// Rotation of an angle-axis vector and its left Jacobian J_l (R(φ + dφ) ≈ exp([J_l dφ]×) R(φ)).
void rotation_and_left_jacobian(const double* aa, Eigen::Matrix3d* R, Eigen::Matrix3d* J) {
  const Eigen::Vector3d phi(aa[0], aa[1], aa[2]);
  const double th = phi.norm();
  const Eigen::Matrix3d K = skew(phi);
  if (th < 1e-8) {
    *R = Eigen::Matrix3d::Identity() + K;
    *J = Eigen::Matrix3d::Identity() + 0.5 * K;
    return;
  }
  *R = Eigen::AngleAxisd(th, phi / th).toRotationMatrix();
  *J = Eigen::Matrix3d::Identity() + (1 - std::cos(th)) / (th * th) * K +
       (th - std::sin(th)) / (th * th * th) * K * K;
}

// One template sample against its scan target: residuals [λn·nᵀ(v − c); λp·(v − c)] times
// `weight` (point-to-plane plus a weaker point-to-point term, §2.2 "up to three constraint
// equations per point"), with analytic Jacobians.
// Parameter blocks: [0] scale (1), [1] root angle-axis (3), [2] translation (3), then the
// chain's joint parameters (slot ≥ 3): an angle-axis (3) or, for a twist bone, an angle about
// the bone's rest axis (1). Several bones of a chain may share one block (tied groups); every
// rotation is relative to the parent bone, in world-aligned axes.
class PointResidual : public ceres::CostFunction {
 public:
  PointResidual(const Chain* chain, const Skeleton* skeleton, const Eigen::Vector3d& x,
                const Eigen::Vector3d& target, const Eigen::Vector3d& normal, double weight,
                double plane_weight, double point_weight, const std::vector<int>& block_sizes)
      : chain_(chain), skeleton_(skeleton), x_(x), target_(target), normal_(normal),
        weight_(weight), plane_weight_(plane_weight), point_weight_(point_weight) {
    set_num_residuals(4);
    auto* sizes = mutable_parameter_block_sizes();
    sizes->push_back(1);
    sizes->push_back(3);
    sizes->push_back(3);
    for (int b : block_sizes) sizes->push_back(b);
  }

  bool Evaluate(double const* const* p, double* r, double** jac) const override {
    const Chain& ch = *chain_;
    const Skeleton& sk = *skeleton_;
    const int m = int(ch.bones.size());
    const double s = p[0][0];
    std::vector<Eigen::Matrix3d> Q(m), J(m);
    std::vector<Eigen::Vector3d> h(m);
    for (int c = 0; c < m; ++c) {
      const int b = ch.bones[c], pc = ch.parent[c];
      Eigen::Matrix3d R;
      if (pc < 0) {
        rotation_and_left_jacobian(p[1], &R, &J[c]);
        Q[c] = R;
        h[c] = sk.heads.row(b).transpose() + Eigen::Map<const Eigen::Vector3d>(p[2]);
        continue;
      }
      h[c] = h[pc] + Q[pc] * (s * (sk.heads.row(b) - sk.heads.row(ch.bones[pc])).transpose());
      if (ch.slot[c] >= 0) {
        const Eigen::Vector3d aa = ch.twist_axis[c].squaredNorm() > 0
                                       ? Eigen::Vector3d(p[ch.slot[c]][0] * ch.twist_axis[c])
                                       : Eigen::Vector3d(Eigen::Map<const Eigen::Vector3d>(p[ch.slot[c]]));
        rotation_and_left_jacobian(aa.data(), &R, &J[c]);
        Q[c] = Q[pc] * R;
      } else {
        Q[c] = Q[pc];
      }
    }
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    std::vector<Eigen::Vector3d> vc(ch.blend.size());
    for (size_t e = 0; e < ch.blend.size(); ++e) {
      const auto& [c, w] = ch.blend[e];
      vc[e] = Q[c] * (s * (x_ - sk.heads.row(ch.bones[c]).transpose())) + h[c];
      v += w * vc[e];
    }
    const Eigen::Vector3d d = v - target_;
    r[0] = weight_ * plane_weight_ * normal_.dot(d);
    for (int k = 0; k < 3; ++k) r[1 + k] = weight_ * point_weight_ * d[k];
    if (!jac) return true;
    // Residual rows as a 4×3 map of dv.
    Eigen::Matrix<double, 4, 3> P;
    P.row(0) = weight_ * plane_weight_ * normal_.transpose();
    P.bottomRows<3>() = weight_ * point_weight_ * Eigen::Matrix3d::Identity();
    const auto& sizes = parameter_block_sizes();
    for (size_t k = 3; k < sizes.size(); ++k)
      if (jac[k]) std::fill(jac[k], jac[k] + 4 * sizes[k], 0.0);
    auto put = [&](int block, const Eigen::MatrixXd& dv, bool add) {
      if (!jac[block]) return;
      Eigen::Map<Eigen::Matrix<double, 4, Eigen::Dynamic, Eigen::RowMajor>> Jm(jac[block], 4,
                                                                                dv.cols());
      if (add) Jm += P * dv;
      else Jm = P * dv;
    };
    const Eigen::Vector3d root_h = h[0];
    put(0, (v - root_h) / s, false);
    put(2, Eigen::Matrix3d::Identity(), false);
    // A rotation at chain bone a moves the points of the bones below it about its posed head:
    // dv = −Σ_e w_e [v_e − h_a]× ω_a,  ω_a = Q_parent(a) J_l(φ_a) dφ_a  (dφ_a = axis·dθ for a
    // twist bone; tied bones add their columns into the shared block).
    for (int a = 0; a < m; ++a) {
      const int block = a == 0 ? 1 : ch.slot[a];
      if (block < 0) continue;
      Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
      for (size_t e = 0; e < ch.blend.size(); ++e)
        if (ch.below[e][a]) M -= ch.blend[e].second * skew(vc[e] - h[a]);
      const Eigen::Matrix3d Qp = a == 0 ? Eigen::Matrix3d::Identity() : Q[ch.parent[a]];
      const Eigen::Matrix3d D = M * Qp * J[a];
      if (a > 0 && ch.twist_axis[a].squaredNorm() > 0)
        put(block, D * ch.twist_axis[a], true);
      else
        put(block, D, a > 0);
    }
    return true;
  }

 private:
  const Chain* chain_;
  const Skeleton* skeleton_;
  Eigen::Vector3d x_, target_, normal_;
  double weight_, plane_weight_, point_weight_;
};

// weight·(aa − centre): towards the rest pose (centre 0) or towards the landmark-only pose.
struct PriorResidual {
  double weight;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  template <typename T>
  bool operator()(const T* aa, T* r) const {
    for (int k = 0; k < 3; ++k) r[k] = T(weight) * (aa[k] - T(centre[k]));
    return true;
  }
};

struct PriorResidual1 {
  double weight;
  double centre = 0.0;
  template <typename T>
  bool operator()(const T* a, T* r) const {
    r[0] = T(weight) * (a[0] - T(centre));
    return true;
  }
};

// weight·(aa · axis): the component of an axis-angle along `axis` (a ball joint's twist).
struct AxisPriorResidual {
  double weight;
  Eigen::Vector3d axis;
  template <typename T>
  bool operator()(const T* aa, T* r) const {
    r[0] = T(weight) * (aa[0] * axis[0] + aa[1] * axis[1] + aa[2] * axis[2]);
    return true;
  }
};

// A prior pulling a joint parameter towards `centre` with `weight`: one residual for a one-dof
// parameter (curl, twist: centre[0]), three for a ball joint's axis-angle.
void add_joint_prior(ceres::Problem& problem, bool one_dof, double weight,
                     const Eigen::Vector3d& centre, Eigen::Vector3d& aa) {
  if (one_dof)
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<PriorResidual1, 1, 1>(
                                 new PriorResidual1{weight, centre[0]}),
                             nullptr, aa.data());
  else
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<PriorResidual, 3, 3>(
                                 new PriorResidual{weight, centre}),
                             nullptr, aa.data());
}

// weight·(a − m): a finger's curl towards its hand's mean curl m.
struct CouplingResidual {
  double weight;
  template <typename T>
  bool operator()(const T* a, const T* m, T* r) const {
    r[0] = T(weight) * (a[0] - m[0]);
    return true;
  }
};

Eigen::Vector3d to_angle_axis(const Eigen::Matrix3d& R) {
  Eigen::AngleAxisd a(R);
  return a.angle() * a.axis();
}
Eigen::Matrix3d from_angle_axis(const Eigen::Vector3d& v) {
  const double a = v.norm();
  if (a < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(a, v / a).toRotationMatrix();
}

}  // namespace

PoseFitResult fit_pose(const Mesh& tpl, const Skeleton& skeleton, const SkinWeights& W,
                       const PointCloud& scan, const std::vector<Landmark>& all_landmarks,
                       const PoseFitOptions& o, PoseFitSummary* summary,
                       const ProgressCallback& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  skeleton.validate();
  const int n = int(tpl.V.rows()), nb = skeleton.bone_count();
  if (W.rows() != n || W.cols() != nb)
    throw InputError("pose fit: skinning weights are " + std::to_string(W.rows()) + " by " +
                     std::to_string(W.cols()) + ", expected " + std::to_string(n) + " by " +
                     std::to_string(nb));
  if (nb == 0 || skeleton.parents[0] != -1)
    throw InputError("pose fit: expected bone 0 to be the skeleton's root");
  for (int b = 1; b < nb; ++b)
    if (skeleton.parents[b] < 0)
      throw InputError("pose fit: the skeleton has more than one root (bone '" +
                       skeleton.names[b] + "')");
  if (scan.P.rows() == 0) throw InputError("pose fit: the scan has no points");
  check_landmarks(all_landmarks, n, "pose fit");

  // Joint parameters: root (always free, separate) + the groups of the option (or the default
  // one-rotation-per-segment set, keeping the bones the skeleton has).
  struct Param {
    std::vector<int> bones;
    bool twist = false;
    double prior = 1.0;
    bool late = false;
    bool curl = false;
    bool anchored = true;
    bool tuck = false;
    bool one_dof() const { return twist || curl || tuck; }
  };
  std::vector<Param> params;
  std::vector<int> free_index(nb, -1);  // bone → its parameter, -1 fixed
  std::vector<int> free_bones = {0};
  {
    std::vector<PoseParameter> spec;
    const bool custom = !o.free_bones.empty() || !o.parameters.empty();
    if (!o.free_bones.empty())
      for (const auto& name : o.free_bones) spec.push_back({{name}, false});
    else
      spec = o.parameters.empty() ? default_pose_parameters() : o.parameters;
    for (const auto& ps : spec) {
      Param prm;
      prm.twist = ps.twist;
      prm.prior = ps.prior;
      prm.late = ps.late;
      prm.curl = ps.curl && !ps.twist;
      prm.anchored = ps.anchored;
      prm.tuck = ps.tuck && !ps.twist && !prm.curl;
      for (const auto& name : ps.bones) {
        const int b = custom ? skeleton.index(name) : skeleton.find(name);
        if (b > 0 && free_index[b] < 0) prm.bones.push_back(b);
      }
      if (prm.bones.empty()) continue;
      for (int b : prm.bones) {
        free_index[b] = int(params.size());
        free_bones.push_back(b);
      }
      params.push_back(prm);
    }
  }
  const int nfree = int(params.size());
  // Rest axis of every bone (for twist parameters).
  std::vector<Eigen::Vector3d> bone_axis(nb, Eigen::Vector3d::Zero());
  for (int b = 0; b < nb; ++b) {
    const Eigen::Vector3d d = (skeleton.tails.row(b) - skeleton.heads.row(b)).transpose();
    if (d.norm() > 1e-12) bone_axis[b] = d.normalized();
  }
  for (const Param& prm : params)
    if (prm.one_dof())
      for (int b : prm.bones)
        if (bone_axis[b].squaredNorm() == 0)
          throw InputError("pose fit: twist or curl bone '" + skeleton.names[b] +
                           "' has zero length");
  // Axis of each 1-DOF bone: its rest direction (twist) or its curl axis, rest direction ×
  // palm normal. The palm normal is the least-variance direction of the heads and tails of
  // the bones below the hand's wrist (the first ancestor named "wrist…", else the
  // grandparent), thumb (finger1…) excluded.
  std::vector<Eigen::Vector3d> dof_axis = bone_axis;
  std::vector<int> hand_of(nb, -1);  // curl bone → its wrist bone
  auto below = [&](int b, int a) {
    for (; b >= 0; b = skeleton.parents[b])
      if (b == a) return true;
    return false;
  };
  // The hand of a finger bone (its wrist) and that hand's palm normal.
  auto hand_wrist = [&](int b) {
    int w = skeleton.parents[b];
    while (w > 0 && skeleton.names[w].rfind("wrist", 0) != 0) w = skeleton.parents[w];
    if (w <= 0) w = std::max(0, skeleton.parents[std::max(0, skeleton.parents[b])]);
    return w;
  };
  auto palm_normal = [&](int b, int w) {
    std::vector<Eigen::Vector3d> pts;
    for (int c = 0; c < nb; ++c)
      if (c != w && below(c, w) && skeleton.names[c].rfind("finger1", 0) != 0) {
        pts.push_back(skeleton.heads.row(c).transpose());
        pts.push_back(skeleton.tails.row(c).transpose());
      }
    if (pts.size() < 6)
      throw InputError("pose fit: cannot find a curl axis for bone '" + skeleton.names[b] +
                       "' (expected a hand of several bones below its wrist)");
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& q : pts) mean += q;
    mean /= double(pts.size());
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    for (const auto& q : pts) C += (q - mean) * (q - mean).transpose();
    Eigen::Vector3d normal = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(C).eigenvectors().col(0);
    // Oriented to the palm side, where the thumb (finger1…) lies: a positive curl then moves
    // the fingertip towards the palm (R(θ)d ≈ d cos θ + n sin θ), so the curl limits below
    // tell flexion from hyperextension.
    Eigen::Vector3d thumb = Eigen::Vector3d::Zero();
    int thumb_points = 0;
    for (int c = 0; c < nb; ++c)
      if (c != w && below(c, w) && skeleton.names[c].rfind("finger1", 0) == 0) {
        thumb += skeleton.heads.row(c).transpose() + skeleton.tails.row(c).transpose();
        thumb_points += 2;
      }
    if (thumb_points > 0 && (thumb / thumb_points - mean).dot(normal) < 0) normal = -normal;
    return std::make_pair(normal, mean);
  };
  for (const Param& prm : params) {
    if (!prm.curl && !prm.tuck) continue;
    for (int b : prm.bones) {
      const int w = hand_wrist(b);
      const auto [normal, centre] = palm_normal(b, w);
      if (prm.tuck) {
        // About the palm normal, signed so that the bone's tail moves towards the palm's centre
        // (across the palm; the same sense on either hand).
        const Eigen::Vector3d tail = skeleton.tails.row(b).transpose();
        const Eigen::Vector3d head = skeleton.heads.row(b).transpose();
        const Eigen::Vector3d move = normal.cross(tail - head);
        dof_axis[b] = move.dot(centre - tail) >= 0 ? normal : Eigen::Vector3d(-normal);
        continue;
      }
      hand_of[b] = w;
      const Eigen::Vector3d axis = bone_axis[b].cross(normal);
      if (axis.norm() < 1e-6)
        throw InputError("pose fit: cannot find a curl axis for bone '" + skeleton.names[b] +
                         "' (expected a hand of several bones below its wrist)");
      dof_axis[b] = axis.normalized();
    }
  }

  // Landmarks on parts the fit keeps rigid far from a fitted joint (less than half of the
  // vertex's weight on bones within two fixed bones of a fitted one: a fingertip with fixed
  // fingers) cannot follow the scan's pose of those parts and would drag the free joints (a
  // fingertip of a fist pulls the forearm); the non-rigid fit uses them instead. Toes and the
  // jaw, one or two rigid bones below the foot or head, do constrain those joints.
  // Counted twice: with the hand stage's (late) parameters fitted, and held at rest as they
  // are in the body stages (a fist's fingertip landmark must not drag the forearm there).
  std::vector<int> rigid_depth(nb, 0), rigid_depth_body(nb, 0);
  std::vector<char> late_bone(nb, 0);  // bone of a late parameter or below one
  for (int b = 1; b < nb; ++b) {
    const int pb = skeleton.parents[b];
    const bool fitted = free_index[b] >= 0;
    const bool late = fitted && params[free_index[b]].late;
    late_bone[b] = late || late_bone[pb];
    rigid_depth[b] = fitted ? 0 : rigid_depth[pb] + 1;
    rigid_depth_body[b] = fitted && !late ? 0 : rigid_depth_body[pb] + 1;
  }
  std::vector<Landmark> landmarks;
  std::vector<char> lm_body;  // landmark used in the landmark and body stages
  for (const Landmark& l : all_landmarks) {
    double movable = 0, movable_body = 0;
    for (SkinWeights::InnerIterator it(W, l.vertex); it; ++it) {
      if (it.col() == 0 || rigid_depth[it.col()] <= o.landmark_rigid_depth) movable += it.value();
      if (it.col() == 0 || rigid_depth_body[it.col()] <= o.landmark_rigid_depth)
        movable_body += it.value();
    }
    if (movable >= 0.5) {
      landmarks.push_back(l);
      lm_body.push_back(movable_body >= 0.5);
    }
  }
  const int body_landmarks = int(std::count(lm_body.begin(), lm_body.end(), 1));
  // Hand-stage samples: template vertices weighted on a late bone; hand region: vertices
  // mostly on late bones or on their parents (palm, wrist), whose closest scan points are the
  // hand's.
  std::vector<int> hand_samples;
  std::vector<char> hand_region(n, 0);
  {
    std::vector<char> hand_bone(nb, 0);
    for (int b = 1; b < nb; ++b)
      if (late_bone[b]) hand_bone[b] = hand_bone[skeleton.parents[b]] = 1;
    std::vector<int> cand;
    for (int i = 0; i < n; ++i) {
      double wl = 0, wh = 0;
      for (SkinWeights::InnerIterator it(W, i); it; ++it) {
        if (late_bone[it.col()]) wl += it.value();
        if (hand_bone[it.col()]) wh += it.value();
      }
      if (wl > 0.25) cand.push_back(i);
      hand_region[i] = wh >= 0.5;
    }
    const int hstride = std::max<int>(1, int(cand.size()) / std::max(1, o.hand_sample_vertices));
    for (size_t k = 0; k < cand.size(); k += hstride) hand_samples.push_back(cand[k]);
  }

  // Sample vertices and their chains.
  const int stride = std::max(1, n / std::max(1, o.sample_vertices));
  std::vector<int> samples;
  for (int i = 0; i < n; i += stride) samples.push_back(i);
  for (const Landmark& l : landmarks) samples.push_back(l.vertex);  // chains for landmarks too
  const int hand_first = int(samples.size());
  samples.insert(samples.end(), hand_samples.begin(), hand_samples.end());
  // Samples mostly on late bones (fingers) do not pair in the body stages: held open, they cannot
  // follow a fist and only shake the wrist (it cycled by 1° for 25 iterations on a fist).
  std::vector<char> on_late(samples.size(), 0);
  for (size_t si = 0; si < samples.size(); ++si) {
    double wl = 0;
    for (SkinWeights::InnerIterator it(W, samples[si]); it; ++it)
      if (late_bone[it.col()]) wl += it.value();
    on_late[si] = wl >= 0.5;
  }
  std::vector<Chain> chains(samples.size());
  std::vector<std::vector<int>> chain_free(samples.size());  // parameter per chain block
  for (size_t si = 0; si < samples.size(); ++si) {
    std::set<int> bones;
    std::vector<std::pair<int, double>> blend;
    for (SkinWeights::InnerIterator it(W, samples[si]); it; ++it) {
      if (it.value() <= 0) continue;
      blend.emplace_back(int(it.col()), it.value());
      for (int b = int(it.col()); b >= 0; b = skeleton.parents[b]) bones.insert(b);
    }
    Chain& ch = chains[si];
    ch.bones.assign(bones.begin(), bones.end());  // sorted: parents first
    if (ch.bones.empty() || ch.bones[0] != 0) {   // unweighted vertex: follows the root
      ch.bones.insert(ch.bones.begin(), 0);
      if (blend.empty()) blend.emplace_back(0, 1.0);
    }
    std::vector<int> pos(nb, -1);
    for (size_t c = 0; c < ch.bones.size(); ++c) pos[ch.bones[c]] = int(c);
    for (size_t c = 0; c < ch.bones.size(); ++c) {
      const int b = ch.bones[c];
      ch.parent.push_back(b == 0 ? -1 : pos[skeleton.parents[b]]);
      if (b != 0 && free_index[b] >= 0) {
        const int k = free_index[b];
        auto& cf = chain_free[si];
        auto at = std::find(cf.begin(), cf.end(), k);
        if (at == cf.end()) at = cf.insert(cf.end(), k);
        ch.slot.push_back(3 + int(at - cf.begin()));
        ch.twist_axis.push_back(params[k].one_dof() ? dof_axis[b] : Eigen::Vector3d::Zero());
      } else {
        ch.slot.push_back(-1);
        ch.twist_axis.push_back(Eigen::Vector3d::Zero());
      }
    }
    for (auto& [b, w] : blend) {
      ch.blend.emplace_back(pos[b], w);
      std::vector<char> below(ch.bones.size(), 0);
      for (int c = pos[b]; c >= 0; c = ch.parent[c]) below[c] = 1;
      ch.below.push_back(std::move(below));
    }
  }

  // Parameters.
  double scale = 1.0;
  Eigen::Vector3d root_aa = Eigen::Vector3d::Zero(), trans = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> joint_aa(nfree, Eigen::Vector3d::Zero());
  const Eigen::Vector3d root_head = skeleton.heads.row(0).transpose();
  // Initial similarity x → s R x + τ, as root rotation R, scale s, t = τ + sR·h_root − h_root.
  {
    double s = 1.0;
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    Eigen::Vector3d tau;
    if (body_landmarks >= 3) {
      Eigen::Matrix3Xd A(3, body_landmarks), B(3, body_landmarks);
      for (size_t k = 0, c = 0; k < landmarks.size(); ++k) {
        if (!lm_body[k]) continue;
        A.col(c) = tpl.V.row(landmarks[k].vertex).transpose();
        B.col(c++) = landmarks[k].target;
      }
      if (o.initial_scale > 0) A *= o.initial_scale;
      const Eigen::Matrix4d T = Eigen::umeyama(A, B, o.fit_scale && !(o.initial_scale > 0));
      const Eigen::Matrix3d sR = T.topLeftCorner<3, 3>();
      s = std::cbrt(sR.determinant());
      R = sR / s;
      if (o.initial_scale > 0) s = o.initial_scale;
      tau = T.topRightCorner<3, 1>();
    } else {
      if (o.initial_scale > 0)
        s = o.initial_scale;
      else if (o.fit_scale)
        s = bounding_box_diagonal(scan.P) / std::max(1e-12, bounding_box_diagonal(tpl.V));
      tau = scan.P.colwise().mean().transpose() - s * tpl.V.colwise().mean().transpose();
    }
    if (!(s > 0) || !std::isfinite(s) || !R.allFinite() || !tau.allFinite())
      throw InputError("pose fit: could not initialise the global alignment from the landmarks "
                       "(are three or more of them collinear or coincident?)");
    scale = s;
    root_aa = to_angle_axis(R);
    trans = tau + s * R * root_head - root_head;
  }

  auto param_rotation = [&](int k, int b) {
    return params[k].one_dof() ? from_angle_axis(joint_aa[k][0] * dof_axis[b])
                           : from_angle_axis(joint_aa[k]);
  };
  auto current_pose = [&] {
    Pose p = Pose::rest(nb);
    p.rotations[0] = from_angle_axis(root_aa);
    p.root_translation = trans;
    for (int k = 0; k < nfree; ++k)
      for (int b : params[k].bones) p.rotations[b] = param_rotation(k, b);
    return p;
  };


  // Residual of sample si (index into `samples`, with its chain) against a scan target, on the
  // current parameter blocks; used by the body, landmark and hand stages.
  auto add_sample = [&](ceres::Problem& problem, int si, const Eigen::Vector3d& target,
                        const Eigen::Vector3d& normal, double weight, double plane_weight,
                        double point_weight, ceres::LossFunction* loss) {
    std::vector<int> sizes;
    for (int k : chain_free[si]) sizes.push_back(params[k].one_dof() ? 1 : 3);
    auto* cost = new PointResidual(&chains[si], &skeleton, tpl.V.row(samples[si]).transpose(),
                                   target, normal, weight, plane_weight, point_weight, sizes);
    std::vector<double*> blocks = {&scale, root_aa.data(), trans.data()};
    for (int k : chain_free[si]) blocks.push_back(joint_aa[k].data());
    problem.AddResidualBlock(cost, loss, blocks);
  };

  PointIndex scan_index(scan.P);
  const double cos_min = std::cos(o.max_normal_angle_deg * M_PI / 180.0);
  PoseFitSummary sum;
  sum.landmarks_used = int(landmarks.size());
  const int nsamples = hand_first - int(landmarks.size());
  // First the landmarks alone pose the body (they are reliable and far-reaching; surface
  // correspondences of a template in the wrong pose are not), then the ICP iterations.
  const int lm_iters = body_landmarks >= 3 ? o.landmark_iterations : 0;
  const int total_iters = lm_iters + o.max_icp_iterations;
  std::vector<Eigen::Vector3d> anchor;  // joint parameters after the landmark-only solves
  for (int iter = 0; iter < total_iters; ++iter) {
    report_progress(progress, double(iter) / total_iters, "pose fit");
    const bool data = iter >= lm_iters;
    const int data_iter = iter - lm_iters;
    if (data_iter == 0 && lm_iters > 0) anchor = joint_aa;
    const Pose pose = current_pose();
    const Eigen::MatrixX3d V = pose_template(tpl.V, skeleton, W, scale, pose);
    const Eigen::MatrixX3d VN = vertex_normals(V, tpl.F);
    const double dmax =
        std::max(o.max_distance, o.initial_max_distance * std::pow(0.5, std::max(0, data_iter)));
    std::vector<int> match(nsamples, -1);
    if (data) tbb::parallel_for(0, nsamples, [&](int si) {
      const int i = samples[si];
      if (on_late[si]) return;
      double d2 = 0;
      const int j = scan_index.nearest(V.row(i).transpose(), &d2);
      if (j < 0 || d2 > dmax * dmax) return;
      if (scan.has_normals()) {
        const double c = scan.N.row(j).dot(VN.row(i));
        if ((o.unsigned_normals ? std::abs(c) : c) < cos_min) return;
      }
      match[si] = j;
    });
    // Scan → template pairs (symmetric ICP): every scan_samples-th scan point pulls its closest
    // template sample. Template→scan pairs alone never pull a template limb towards scan
    // surface it does not already face (an arm stuck against the torso matches the torso).
    std::vector<std::pair<int, int>> back;  // (sample, scan point)
    if (data && o.symmetric_weight > 0) {
      Eigen::MatrixX3d SV(nsamples, 3);
      for (int si = 0; si < nsamples; ++si) SV.row(si) = V.row(samples[si]);
      PointIndex sample_index(SV);
      const int m = int(scan.P.rows());
      const int sstride = std::max(1, m / std::max(1, o.scan_samples));
      const int count = (m + sstride - 1) / sstride;
      std::vector<int> bmatch(count, -1);
      tbb::parallel_for(0, count, [&](int k) {
        const int j = k * sstride;
        double d2 = 0;
        const int si = sample_index.nearest(scan.P.row(j).transpose(), &d2);
        if (si < 0 || d2 > dmax * dmax || on_late[si]) return;
        if (scan.has_normals()) {
          const double c = scan.N.row(j).dot(VN.row(samples[si]));
          if ((o.unsigned_normals ? std::abs(c) : c) < cos_min) return;
        }
        bmatch[k] = si;
      });
      for (int k = 0; k < count; ++k)
        if (bmatch[k] >= 0) back.emplace_back(bmatch[k], k * sstride);
    }
    // Trimming: after the first data iteration, drop the worst trim_fraction of each direction's
    // pairs (occluded or wrongly matched surface).
    double trim_fwd = std::numeric_limits<double>::infinity(), trim_back = trim_fwd;
    if (data && data_iter >= 1 && o.trim_fraction > 0) {
      auto quantile = [&](std::vector<double> d) {
        if (d.size() < 10) return std::numeric_limits<double>::infinity();
        const size_t k = size_t((1.0 - o.trim_fraction) * double(d.size() - 1));
        std::nth_element(d.begin(), d.begin() + k, d.end());
        return d[k];
      };
      std::vector<double> df, db;
      for (int si = 0; si < nsamples; ++si)
        if (match[si] >= 0) df.push_back((V.row(samples[si]) - scan.P.row(match[si])).norm());
      for (const auto& [si, j] : back) db.push_back((V.row(samples[si]) - scan.P.row(j)).norm());
      trim_fwd = quantile(df);
      trim_back = quantile(db);
    }

    ceres::Problem problem;
    std::vector<double*> blocks_all;
    problem.AddParameterBlock(&scale, 1);
    problem.AddParameterBlock(root_aa.data(), 3);
    problem.AddParameterBlock(trans.data(), 3);
    for (int k = 0; k < nfree; ++k)
      problem.AddParameterBlock(joint_aa[k].data(), params[k].one_dof() ? 1 : 3);
    for (int k = 0; k < nfree; ++k)
      if (params[k].late) problem.SetParameterBlockConstant(joint_aa[k].data());
    if (!o.fit_scale) problem.SetParameterBlockConstant(&scale);
    else problem.SetParameterLowerBound(&scale, 0, 0.2);
    int matched = 0;
    double d2sum = 0;
    for (int si = 0; si < nsamples; ++si) {
      if (match[si] < 0) continue;
      const Eigen::Vector3d target = scan.P.row(match[si]).transpose();
      const double d2 = (V.row(samples[si]).transpose() - target).squaredNorm();
      if (d2 > trim_fwd * trim_fwd) continue;
      ++matched;
      d2sum += d2;
      const Eigen::Vector3d normal = scan.has_normals() ? Eigen::Vector3d(scan.N.row(match[si]))
                                                        : Eigen::Vector3d::Zero();
      add_sample(problem, si, target, normal, 1.0, 1.0, o.point_to_point_weight,
                new ceres::HuberLoss(o.robust_scale));
    }
    if (!back.empty()) {
      // Both directions weigh the same in total.
      const double w = o.symmetric_weight * std::sqrt(double(std::max(matched, 1)) / back.size());
      for (const auto& [si, j] : back) {
        const Eigen::Vector3d target = scan.P.row(j).transpose();
        if ((V.row(samples[si]).transpose() - target).norm() > trim_back) continue;
        const Eigen::Vector3d normal =
            scan.has_normals() ? Eigen::Vector3d(scan.N.row(j)) : Eigen::Vector3d::Zero();
        add_sample(problem, si, target, normal, w, 1.0, o.point_to_point_weight,
                  new ceres::HuberLoss(o.robust_scale));
      }
    }
    double l2 = 0;
    for (size_t k = 0; k < landmarks.size(); ++k) {
      if (!lm_body[k]) continue;
      const int si = nsamples + int(k);
      l2 += (V.row(landmarks[k].vertex).transpose() - landmarks[k].target).squaredNorm();
      add_sample(problem, si, landmarks[k].target, Eigen::Vector3d::Zero(),
                o.landmark_weight * std::sqrt(double(nsamples) / 100.0), 0.0, 1.0, nullptr);
    }
    // Prior per bone: a tied group of g bones costs g times its shared rotation.
    for (int k = 0; k < nfree; ++k) {
      const double anneal =
          data ? std::max(1.0, o.initial_prior_factor * std::pow(0.5, data_iter))
               : std::pow(o.landmark_prior_factor,
                          lm_iters > 1 ? double(lm_iters - 1 - iter) / double(lm_iters - 1) : 1.0);
      const double w = std::sqrt(anneal * o.pose_prior * params[k].prior * double(params[k].bones.size()));
      add_joint_prior(problem, params[k].one_dof(), w, Eigen::Vector3d::Zero(), joint_aa[k]);
      if (data && !anchor.empty() && o.anchor_prior > 0 && !params[k].late &&
          params[k].anchored) {
        const double wa = std::sqrt(o.anchor_prior * double(params[k].bones.size()));
        add_joint_prior(problem, params[k].one_dof(), wa, anchor[k], joint_aa[k]);
      }
    }
    sum.rms = matched ? std::sqrt(d2sum / matched) : 0.0;
    sum.matched_samples = matched;
    sum.landmark_rms = body_landmarks == 0 ? 0.0 : std::sqrt(l2 / body_landmarks);
    if (data && matched + body_landmarks < 10)
      throw InputError("pose fit: only " + std::to_string(matched) +
                       " template samples found a scan point within " + std::to_string(dmax) +
                       " mm and 30° — the scan does not overlap the template (wrong unit or "
                       "far-off position? supply landmarks)");

    const double old_scale = scale;
    const Eigen::Vector3d old_root = root_aa, old_trans = trans;
    const std::vector<Eigen::Vector3d> old_joints = joint_aa;
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
    so.max_num_iterations = data ? o.solver_iterations : 50;
    so.num_threads = o.threads;
    so.logging_type = ceres::SILENT;
    ceres::Solver::Summary cs;
    ceres::Solve(so, &problem, &cs);

    double max_deg = (from_angle_axis(root_aa) * from_angle_axis(old_root).transpose())
                         .eval()
                         .trace();
    max_deg = std::acos(std::clamp((max_deg - 1) / 2, -1.0, 1.0)) * 180 / M_PI;
    for (int k = 0; k < nfree; ++k) {
      const Eigen::Vector3d a = params[k].one_dof() ? Eigen::Vector3d(joint_aa[k][0], 0, 0) : joint_aa[k];
      const Eigen::Vector3d b = params[k].one_dof() ? Eigen::Vector3d(old_joints[k][0], 0, 0) : old_joints[k];
      const Eigen::Matrix3d D = from_angle_axis(a) * from_angle_axis(b).transpose();
      max_deg = std::max(max_deg,
                         std::acos(std::clamp((D.trace() - 1) / 2, -1.0, 1.0)) * 180 / M_PI);
    }
    const double dmm = (trans - old_trans).norm() + std::abs(scale - old_scale) * 1000.0;
    sum.icp_iterations = iter + 1;
    if (data_iter > 0 && dmax <= o.max_distance && max_deg < o.convergence_deg &&
        dmm < o.convergence_mm) {
      sum.converged = true;
      break;
    }
  }
  // Hand stage: the late parameters (finger curls, thumbs) against the hand's scan points,
  // the body held where it converged.
  std::vector<int> late_params;
  for (int k = 0; k < nfree; ++k)
    if (params[k].late) late_params.push_back(k);
  // With hand_wrists, the wrists (the fitted parameters right above the late ones) are refitted
  // with them: the body stage places a hand by few, mostly forearm, correspondences.
  // With hand_forearm_twist, so is the twist parameter right above each wrist (the forearm's).
  // hand_wrist_of: the wrist bone of each hand parameter (the first fitted body bone above a
  // late one).
  std::vector<char> hand_free(nfree, 0);
  std::vector<int> hand_wrist_of(nfree, -1);
  auto fitted_above = [&](int b) {
    int a = skeleton.parents[b];
    while (a > 0 && free_index[a] < 0) a = skeleton.parents[a];
    return a;
  };
  for (int k : late_params) {
    hand_free[k] = 1;
    int a = params[k].bones[0];
    do a = fitted_above(a);
    while (a > 0 && params[free_index[a]].late);
    hand_wrist_of[k] = std::max(a, 0);
    if (!o.hand_wrists || a <= 0) continue;
    hand_free[free_index[a]] = 1;
    hand_wrist_of[free_index[a]] = a;
    const int t = fitted_above(a);
    if (o.hand_forearm_twist && t > 0 && params[free_index[t]].twist) {
      hand_free[free_index[t]] = 1;
      hand_wrist_of[free_index[t]] = a;
    }
  }
  std::vector<int> hand_params;
  for (int k = 0; k < nfree; ++k)
    if (hand_free[k]) hand_params.push_back(k);
  if (!late_params.empty() && !hand_samples.empty() && o.hand_iterations > 0) {
    const int nh = int(hand_samples.size());
    // Coupling groups: the curl parameters of one hand.
    std::map<int, std::vector<int>> coupled;  // wrist bone → curl parameters
    for (int k : late_params)
      if (params[k].curl) coupled[hand_of[params[k].bones[0]]].push_back(k);
    // Phases: first (tied_hand_phase) the fingers of a hand curl as one (a grasp, robust where
    // single fingers are poorly scanned, e.g. the inside of a fist), then each on its own,
    // started there; the per-finger acceptance below reverts to the start of the last phase.
    std::vector<Eigen::Vector3d> hand_start = joint_aa;
    // One hand stage from the current joint values: the phases, then the per-finger acceptance.
    auto run_hand_stage = [&] {
      const int run_first_iteration = sum.hand_iterations;
      const int phases = o.tied_hand_phase ? 2 : 1;
      for (int phase = 0; phase < phases; ++phase) {
      const double coupling = phase + 1 < phases ? 1e8 : o.finger_coupling;
      hand_start = joint_aa;
      for (int hiter = 0; hiter < o.hand_iterations; ++hiter) {
        report_progress(progress, 0.95, "pose fit: hands");
        const Eigen::MatrixX3d V = pose_template(tpl.V, skeleton, W, scale, current_pose());
        const Eigen::MatrixX3d VN = vertex_normals(V, tpl.F);
        const double dmax = std::max(o.hand_max_distance,
                                     o.hand_initial_max_distance * std::pow(0.5, hiter));
        // Scan points of the hand: within dmax of the posed hand's box and closest to a hand
        // vertex of the posed template.
        Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
        Eigen::Vector3d hi = -lo;
        for (int i = 0; i < n; ++i)
          if (hand_region[i]) {
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
          is_hand[c] = i >= 0 && hand_region[i];
        });
        std::vector<int> hand_points;
        for (size_t c = 0; c < cand.size(); ++c)
          if (is_hand[c]) hand_points.push_back(cand[c]);
        if (hand_points.size() < 10) break;
        Eigen::MatrixX3d HP(hand_points.size(), 3);
        for (size_t c = 0; c < hand_points.size(); ++c) HP.row(c) = scan.P.row(hand_points[c]);
        PointIndex hand_index(HP);
        Eigen::MatrixX3d SV(nh, 3);
        for (int h = 0; h < nh; ++h) SV.row(h) = V.row(hand_samples[h]);
        PointIndex sample_index(SV);
        auto normal_ok = [&](int j, int i) {
          if (!scan.has_normals()) return true;
          const double c = scan.N.row(j).dot(VN.row(i));
          return (o.unsigned_normals ? std::abs(c) : c) >= cos_min;
        };
        std::vector<int> fwd(nh, -1);
        tbb::parallel_for(0, nh, [&](int h) {
          double d2 = 0;
          const int c = hand_index.nearest(SV.row(h).transpose(), &d2);
          if (c >= 0 && d2 <= dmax * dmax && normal_ok(hand_points[c], hand_samples[h]))
            fwd[h] = hand_points[c];
        });
        const int hp = int(hand_points.size());
        const int bstride = std::max(1, hp / std::max(1, nh));
        std::vector<int> bwd((hp + bstride - 1) / bstride, -1);
        tbb::parallel_for(0, int(bwd.size()), [&](int k) {
          const int j = hand_points[k * bstride];
          double d2 = 0;
          const int h = sample_index.nearest(scan.P.row(j).transpose(), &d2);
          if (h >= 0 && d2 <= dmax * dmax && normal_ok(j, hand_samples[h])) bwd[k] = h;
        });
        ceres::Problem problem;
        problem.AddParameterBlock(&scale, 1);
        problem.AddParameterBlock(root_aa.data(), 3);
        problem.AddParameterBlock(trans.data(), 3);
        for (int k = 0; k < nfree; ++k)
          problem.AddParameterBlock(joint_aa[k].data(), params[k].one_dof() ? 1 : 3);
        problem.SetParameterBlockConstant(&scale);
        problem.SetParameterBlockConstant(root_aa.data());
        problem.SetParameterBlockConstant(trans.data());
        for (int k = 0; k < nfree; ++k)
          if (!hand_free[k] || params[k].tuck) problem.SetParameterBlockConstant(joint_aa[k].data());
        if (o.curl_max_deg > o.curl_min_deg)
          for (int k : hand_params)
            if (params[k].curl) {
              joint_aa[k][0] = std::clamp(joint_aa[k][0], o.curl_min_deg * M_PI / 180.0,
                                          o.curl_max_deg * M_PI / 180.0);
              problem.SetParameterLowerBound(joint_aa[k].data(), 0, o.curl_min_deg * M_PI / 180.0);
              problem.SetParameterUpperBound(joint_aa[k].data(), 0, o.curl_max_deg * M_PI / 180.0);
            }
        int matched = 0;
        double d2sum = 0;
        for (int h = 0; h < nh; ++h) {
          if (fwd[h] < 0) continue;
          const Eigen::Vector3d target = scan.P.row(fwd[h]).transpose();
          d2sum += (SV.row(h).transpose() - target).squaredNorm();
          ++matched;
          const Eigen::Vector3d normal =
              scan.has_normals() ? Eigen::Vector3d(scan.N.row(fwd[h])) : Eigen::Vector3d::Zero();
          add_sample(problem, hand_first + h, target, normal, 1.0, 1.0, o.point_to_point_weight,
                    new ceres::HuberLoss(o.robust_scale));
        }
        int nback = 0;
        for (int b : bwd) nback += b >= 0;
        if (nback > 0) {
          const double w = std::sqrt(double(std::max(matched, 1)) / nback);
          for (size_t k = 0; k < bwd.size(); ++k) {
            if (bwd[k] < 0) continue;
            const int j = hand_points[k * bstride];
            const Eigen::Vector3d normal =
                scan.has_normals() ? Eigen::Vector3d(scan.N.row(j)) : Eigen::Vector3d::Zero();
            add_sample(problem, hand_first + bwd[k], scan.P.row(j).transpose(), normal, w, 1.0,
                      o.point_to_point_weight, new ceres::HuberLoss(o.robust_scale));
          }
        }
        if (matched + nback < 10) break;
        for (size_t k = 0; k < landmarks.size(); ++k)
          if (!lm_body[k])
            add_sample(problem, nsamples + int(k), landmarks[k].target, Eigen::Vector3d::Zero(),
                      o.landmark_weight * std::sqrt(double(nh) / 100.0), 0.0, 1.0, nullptr);
        for (int k : hand_params) {
          if (params[k].tuck) continue;  // held where the start put it
          const double w = std::sqrt(o.pose_prior * params[k].prior * double(params[k].bones.size()));
          add_joint_prior(problem, params[k].one_dof(), w, Eigen::Vector3d::Zero(), joint_aa[k]);
          // The wrists' twist (a ball joint's rotation about its bone, approximated by the
          // axis-angle's component along the rest axis: exact for a pure twist).
          if (o.wrist_twist_prior > 0 && !params[k].late && !params[k].one_dof())
            problem.AddResidualBlock(
                new ceres::AutoDiffCostFunction<AxisPriorResidual, 1, 3>(new AxisPriorResidual{
                    std::sqrt(o.wrist_twist_prior * double(params[k].bones.size())),
                    bone_axis[params[k].bones[0]]}),
                nullptr, joint_aa[k].data());
        }
        // Each finger's curl towards its hand's mean curl (the mean a free variable).
        std::vector<double> means;
        means.reserve(coupled.size());
        if (coupling > 0)
          for (const auto& [wrist, ks] : coupled) {
            if (ks.size() < 2) continue;
            double m = 0;
            for (int k : ks) m += joint_aa[k][0];
            means.push_back(m / ks.size());
            for (int k : ks)
              problem.AddResidualBlock(
                  new ceres::AutoDiffCostFunction<CouplingResidual, 1, 1, 1>(new CouplingResidual{
                      std::sqrt(coupling * double(params[k].bones.size()))}),
                  nullptr, joint_aa[k].data(), &means.back());
          }
        std::vector<Eigen::Vector3d> old = joint_aa;
        ceres::Solver::Options so;
        so.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
        so.max_num_iterations = o.solver_iterations;
        so.num_threads = o.threads;
        so.logging_type = ceres::SILENT;
        ceres::Solver::Summary cs;
        ceres::Solve(so, &problem, &cs);
        ++sum.hand_iterations;
        sum.hand_rms = matched ? std::sqrt(d2sum / matched) : 0.0;
        double max_deg = 0;
        for (int k : hand_params)
          max_deg = std::max(max_deg, (joint_aa[k] - old[k]).norm() * 180.0 / M_PI);
        if (dmax <= o.hand_max_distance && max_deg < o.convergence_deg) break;
      }
      }
      if (o.hand_accept_cap > 0 && sum.hand_iterations > run_first_iteration) {
        // Per-finger acceptance: a hand parameter keeps its fitted value only if that lowers the
        // hand's two-sided distance to the scan (capped at hand_accept_cap), else it goes back to
        // where the hand stage started it (the rest pose's fingers). Scan holes between fingers
        // and fingers touching the body give the hand stage correspondences that curl a straight
        // finger; the distance of the whole result is what tells.
        std::vector<int> hv;
        for (int i = 0; i < n; ++i)
          if (hand_region[i]) hv.push_back(i);
        const double cap = o.hand_accept_cap;
        // The scan points compared: closest (over the whole posed template) to a hand vertex in
        // the start or the fitted pose, and within cap of it.
        std::vector<char> in_set(scan.P.rows(), 0);
        auto collect = [&](const Eigen::MatrixX3d& V) {
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
            if (i >= 0 && hand_region[i] && d2 <= cap * cap) in_set[j] = 1;
          });
        };
        std::vector<Eigen::Vector3d> fitted = joint_aa;
        for (int k : hand_params) joint_aa[k] = hand_start[k];
        collect(pose_template(tpl.V, skeleton, W, scale, current_pose()));
        joint_aa = fitted;
        collect(pose_template(tpl.V, skeleton, W, scale, current_pose()));
        std::vector<int> set;
        for (Eigen::Index j = 0; j < scan.P.rows(); ++j)
          if (in_set[j]) set.push_back(int(j));
        auto hand_cost = [&] {
          const Eigen::MatrixX3d V = pose_template(tpl.V, skeleton, W, scale, current_pose());
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
            scan_index.nearest(H.row(c).transpose(), &d2);
            b[c] = std::min(std::sqrt(d2), cap);
          });
          double sa = 0, sb = 0;
          for (double x : a) sa += x;
          for (double x : b) sb += x;
          return 0.5 * (sa / std::max<size_t>(1, a.size()) + sb / std::max<size_t>(1, b.size()));
        };
        double best = hand_cost();
        sum.hand_accept_before = best;
        for (int k : hand_params) {
          if (joint_aa[k] == hand_start[k]) continue;
          const Eigen::Vector3d keep = joint_aa[k];
          joint_aa[k] = hand_start[k];
          const double c = hand_cost();
          if (c < best) {
            best = c;
            ++sum.hand_reverted;
          } else {
            joint_aa[k] = keep;
          }
        }
        sum.hand_accept_after = best;
      }
    };
    // The hand stage from several starts (PoseFitOptions::hand_start_curls_deg): the fingers
    // open, then a fist; each hand keeps the start whose result is closest to the scan both
    // ways (a later start by a margin). Started open only, a fist whose inside is not scanned
    // was fitted with the fingers 100–120° off and the wrist turned 58° to lay the open hand's
    // back over the fist (s008_p3: hand two-sided distance 12.3 mm against 3.6 mm for the true
    // pose; right-hand flips 700 → 114 with the fist start).
    const std::vector<Eigen::Vector3d> body_joints = joint_aa;
    const size_t nstarts = std::max<size_t>(1, o.hand_start_curls_deg.size());
    auto run_start = [&](size_t s) {
      joint_aa = body_joints;
      if (!o.hand_start_curls_deg.empty())
        for (int k : hand_params) {
          if (params[k].curl) joint_aa[k][0] = o.hand_start_curls_deg[s] * M_PI / 180.0;
          if (params[k].tuck)
            joint_aa[k][0] =
                s < o.hand_start_tucks_deg.size() ? o.hand_start_tucks_deg[s] * M_PI / 180.0 : 0.0;
          if (!params[k].late && params[k].twist && s < o.hand_start_twists_deg.size())
            joint_aa[k][0] += o.hand_start_twists_deg[s] * M_PI / 180.0;
        }
      run_hand_stage();
    };
    if (nstarts == 1) {
      run_start(0);
    } else {
      // The hand of each hand parameter (its wrist: the first fitted body bone above it) and of
      // each hand-region vertex (its heaviest bone's hand).
      const std::vector<int>& hand_id = hand_wrist_of;
      std::vector<char> is_hand_bone(nb, 0);
      for (int k : hand_params) is_hand_bone[hand_id[k]] = 1;
      std::vector<int> hands;
      for (int b = 0; b < nb; ++b)
        if (is_hand_bone[b]) hands.push_back(b);
      std::vector<int> vertex_hand(n, -1);
      for (int i = 0; i < n; ++i) {
        if (!hand_region[i]) continue;
        int b = -1;
        double best = 0;
        for (SkinWeights::InnerIterator it(W, i); it; ++it)
          if (it.value() > best) best = it.value(), b = int(it.col());
        for (; b >= 0; b = skeleton.parents[b])
          if (is_hand_bone[b]) {
            vertex_hand[i] = int(std::find(hands.begin(), hands.end(), b) - hands.begin());
            break;
          }
      }
      const double cap = o.hand_accept_cap > 0 ? o.hand_accept_cap : 30.0;
      const int nhands = int(hands.size());
      // Slot nstarts: the body stage's hand (no hand stage), see hand_compare_body_stage.
      std::vector<std::vector<Eigen::Vector3d>> results(nstarts + 1);
      std::vector<Eigen::MatrixX3d> Vs(nstarts + 1);
      // For each result, the hand of every scan point's closest template vertex (within cap).
      std::vector<std::vector<int>> near_hand(nstarts + 1);
      auto record = [&](size_t s) {
        results[s] = joint_aa;
        Vs[s] = pose_template(tpl.V, skeleton, W, scale, current_pose());
        near_hand[s].assign(scan.P.rows(), -1);
        PointIndex vertex_index(Vs[s]);
        tbb::parallel_for(0, int(scan.P.rows()), [&](int j) {
          double d2 = 0;
          const int i = vertex_index.nearest(scan.P.row(j).transpose(), &d2);
          if (i >= 0 && vertex_hand[i] >= 0 && d2 <= cap * cap) near_hand[s][j] = vertex_hand[i];
        });
      };
      // The scan points compared for hand h between results a and b: those whose closest
      // template vertex (within cap) is on hand h in a, or, where none is on a hand in a, in b.
      auto compared_points = [&](int h, size_t a, size_t b) {
        std::vector<int> set;
        for (Eigen::Index j = 0; j < scan.P.rows(); ++j) {
          const int first = near_hand[a][j] >= 0 ? near_hand[a][j] : near_hand[b][j];
          if (first == h) set.push_back(int(j));
        }
        return set;
      };
      // Two-sided distance of hand h in result s against the scan points `set`, after the
      // translation that best aligns it (a few alternating steps): the pose stage cannot move
      // the wrist, and a hand 10 mm off (s003_p0) otherwise favours a compact fist over the open
      // hand it is.
      auto start_cost = [&](int h, size_t s, const std::vector<int>& set) {
        std::vector<int> hv;
        for (int i = 0; i < n; ++i)
          if (vertex_hand[i] == h) hv.push_back(i);
        if (hv.empty() || set.empty()) return std::numeric_limits<double>::quiet_NaN();
        Eigen::MatrixX3d H(hv.size(), 3);
        for (size_t c = 0; c < hv.size(); ++c) H.row(c) = Vs[s].row(hv[c]);
        PointIndex hand_index(H);
        Eigen::Vector3d t = Eigen::Vector3d::Zero();
        double sa = 0, sb = 0;
        for (int step = 0; step <= o.hand_start_align_steps; ++step) {
          sa = sb = 0;
          Eigen::Vector3d shift = Eigen::Vector3d::Zero();
          int pairs = 0;
          for (int j : set) {
            double d2 = 0;
            const Eigen::Vector3d q = scan.P.row(j).transpose();
            const int i = hand_index.nearest(q - t, &d2);
            const double d = std::sqrt(d2);
            sa += std::min(d, cap);
            if (i >= 0 && d < cap) shift += q - (H.row(i).transpose() + t), ++pairs;
          }
          for (int i = 0; i < H.rows(); ++i) {
            double d2 = 0;
            const Eigen::Vector3d v = H.row(i).transpose() + t;
            const int j = scan_index.nearest(v, &d2);
            const double d = std::sqrt(d2);
            sb += std::min(d, cap);
            if (j >= 0 && d < cap) shift += scan.P.row(j).transpose() - v, ++pairs;
          }
          if (pairs > 0) t += shift / pairs;
        }
        return 0.5 * (sa / set.size() + sb / H.rows());
      };
      // Per hand, each start in turn challenges the best so far, both compared on the scan
      // points closest to that hand in either of the two results (a start's points do not
      // weigh in a comparison it is not part of). A later start must beat the first (open) by
      // the margin; later starts compare as they are.
      // A start whose fingers start as an earlier one's (the tucked thumbs of the fist) is that
      // start's variant: it challenges only that start, once it is the best, and is not run if
      // no hand kept it. Challenging the open hand, fight02's claw (knuckles bent backwards,
      // thumb half tucked) took a fist with tucked thumbs 13 % closer than the open hand it is
      // fitted as, and that scan of the 15 in the database flipped 84 triangles instead of 49.
      auto curl_of = [&](size_t s) {
        return s < o.hand_start_curls_deg.size() ? o.hand_start_curls_deg[s] : 0.0;
      };
      std::vector<int> choice(nhands, 0);
      for (size_t s = 0; s < nstarts; ++s) {
        size_t base = s;
        for (size_t e = 0; e < s && base == s; ++e)
          if (curl_of(e) == curl_of(s)) base = e;
        if (base != s && std::find(choice.begin(), choice.end(), int(base)) == choice.end())
          continue;
        // A twisted start without a refitted forearm twist would repeat its base start.
        if (s < o.hand_start_twists_deg.size() && o.hand_start_twists_deg[s] != 0.0 &&
            std::none_of(hand_params.begin(), hand_params.end(),
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
          sum.hand_start_comparisons.push_back({h, int(w), int(s), cw, cs});
          const double compared_w = w == 0 ? cw : cw / (1.0 - o.hand_start_margin);
          if (cs / (1.0 - o.hand_start_margin) < compared_w) choice[h] = int(s);
        }
      }
      if (o.hand_compare_body_stage) {
        // The chosen result of each hand against the body stage's hand, on the same terms
        // (margin 0): the hand stage must bring the hand closer to the scan to be kept.
        joint_aa = body_joints;
        record(nstarts);
        for (int h = 0; h < nhands; ++h) {
          const size_t w = size_t(choice[h]);
          const std::vector<int> set = compared_points(h, w, nstarts);
          const double cw = start_cost(h, w, set), cb = start_cost(h, nstarts, set);
          if (!(cw == cw) || !(cb == cb)) continue;
          sum.hand_start_comparisons.push_back({h, int(w), int(nstarts), cw, cb});
          if (cb <= cw) choice[h] = int(nstarts);
        }
      }
      joint_aa = results[0];
      for (int k : hand_params) {
        const int h = int(std::find(hands.begin(), hands.end(), hand_id[k]) - hands.begin());
        joint_aa[k] = results[choice[h]][k];
      }
      for (int h = 0; h < nhands; ++h) sum.hand_start_choice.push_back(choice[h]);
    }
  }
  PoseFitResult result;
  result.scale = scale;
  result.pose = current_pose();
  result.V = pose_template(tpl.V, skeleton, W, scale, result.pose);
  result.free_bones = free_bones;
  if (!result.V.allFinite()) throw NumericalError("pose fit produced non-finite vertices");
  {  // Two-sided distance of the result (truncated at max_distance): comparable across options.
    const double cap = o.max_distance;
    PointIndex vertex_index(result.V);
    const int m = int(scan.P.rows());
    const int sstride = std::max(1, m / 20000), vstride = std::max(1, n / 5000);
    double a = 0, b = 0;
    int na = 0, nb2 = 0;
    for (int j = 0; j < m; j += sstride, ++na) {
      double d2 = 0;
      vertex_index.nearest(scan.P.row(j).transpose(), &d2);
      a += std::min(std::sqrt(d2), cap);
    }
    for (int i = 0; i < n; i += vstride, ++nb2) {
      double d2 = 0;
      scan_index.nearest(result.V.row(i).transpose(), &d2);
      b += std::min(std::sqrt(d2), cap);
    }
    sum.two_sided_mm = 0.5 * (a / std::max(na, 1) + b / std::max(nb2, 1));
  }
  report_progress(progress, 1.0, "pose fit");
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (summary) *summary = sum;
  return result;
}

}  // namespace bodymodel
