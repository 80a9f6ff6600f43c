#include "registration/pose_parameters.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <utility>

#include "core/error.h"
#include "core/rotation.h"

namespace bodymodel {

const std::vector<PoseParameter>& segment_pose_parameters() {
  static const std::vector<PoseParameter> params = [] {
    // One rotation per body segment: left independent, MakeHuman's consecutive bones
    // counter-rotate to absorb the subject's proportions at no data cost
    // (docs/pose_fit.md#parameterisations). spine05 and pelvis.L/R stay at rest: they carry
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
      // Hands: one grasp rotation shared by the 12 phalanges of the four fingers, one for the
      // thumb; weak priors (a fist curls 3 × 70° per finger); not anchored to the landmark-only
      // pose, which holds them open.
      std::vector<std::string> fingers;
      for (int f = 2; f <= 5; ++f)
        for (int k = 1; k <= 3; ++k) fingers.push_back(b(("finger" + std::to_string(f) + "-" + std::to_string(k)).c_str()));
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
    // One curl angle per finger shared by its three phalanges, weak prior, hand stage only.
    for (int f = 2; f <= 5; ++f) {
      std::vector<std::string> finger;
      for (int k = 1; k <= 3; ++k)
        finger.push_back(b("finger" + std::to_string(f) + "-" + std::to_string(k)));
      p.push_back({finger, false, 0.1, true, true});
    }
    // The thumb: a ball joint at its base only (finger1-1), prior 1.
    p.push_back({{b("finger1-1")}, false, 1.0, true, false});
    // The thumb's tuck across the palm (finger1-2, finger1-3): set by the hand stage's start,
    // never fitted.
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

namespace {

// Whether bone b is bone a or below it.
bool is_below(const Skeleton& skeleton, int b, int a) {
  for (; b >= 0; b = skeleton.parents[b])
    if (b == a) return true;
  return false;
}

// The hand of a finger bone: its first ancestor named "wrist…", else its grandparent.
int hand_wrist(const Skeleton& skeleton, int b) {
  int w = skeleton.parents[b];
  while (w > 0 && skeleton.names[w].rfind("wrist", 0) != 0) w = skeleton.parents[w];
  if (w <= 0) w = std::max(0, skeleton.parents[std::max(0, skeleton.parents[b])]);
  return w;
}

// The palm normal of the hand below wrist w (for bone b, named in errors) and the palm's centre:
// the least-variance direction of the heads and tails of the bones below the wrist, thumb
// (finger1…) excluded, oriented to the palm side, where the thumb lies. A positive curl then
// moves the fingertip towards the palm (R(θ)d ≈ d cos θ + n sin θ), so the curl limits tell
// flexion from hyperextension.
std::pair<Eigen::Vector3d, Eigen::Vector3d> palm_normal(const Skeleton& skeleton, int b, int w) {
  const int nb = skeleton.bone_count();
  std::vector<Eigen::Vector3d> pts;
  for (int c = 0; c < nb; ++c)
    if (c != w && is_below(skeleton, c, w) && skeleton.names[c].rfind("finger1", 0) != 0) {
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
  Eigen::Vector3d thumb = Eigen::Vector3d::Zero();
  int thumb_points = 0;
  for (int c = 0; c < nb; ++c)
    if (c != w && is_below(skeleton, c, w) && skeleton.names[c].rfind("finger1", 0) == 0) {
      thumb += skeleton.heads.row(c).transpose() + skeleton.tails.row(c).transpose();
      thumb_points += 2;
    }
  if (thumb_points > 0 && (thumb / thumb_points - mean).dot(normal) < 0) normal = -normal;
  return std::make_pair(normal, mean);
}

// The groups to fit (see resolve_pose_parameters) as bone indices into `z`.
void resolve_groups(const Skeleton& skeleton, const std::vector<std::string>& free_bones,
                    const std::vector<PoseParameter>& parameters, PoseParameterization& z) {
  const int nb = skeleton.bone_count();
  z.free_index.assign(nb, -1);
  z.free_bones = {0};
  std::vector<PoseParameter> spec;
  const bool custom = !free_bones.empty() || !parameters.empty();
  if (!free_bones.empty())
    for (const auto& name : free_bones) spec.push_back({{name}, false});
  else
    spec = parameters.empty() ? default_pose_parameters() : parameters;
  for (const auto& ps : spec) {
    FittedParameter prm;
    prm.twist = ps.twist;
    prm.prior = ps.prior;
    prm.late = ps.late;
    prm.curl = ps.curl && !ps.twist;
    prm.anchored = ps.anchored;
    prm.tuck = ps.tuck && !ps.twist && !prm.curl;
    for (const auto& name : ps.bones) {
      const int b = custom ? skeleton.index(name) : skeleton.find(name);
      if (b > 0 && z.free_index[b] < 0) prm.bones.push_back(b);
    }
    if (prm.bones.empty()) continue;
    for (int b : prm.bones) {
      z.free_index[b] = int(z.params.size());
      z.free_bones.push_back(b);
    }
    z.params.push_back(prm);
  }
}

}  // namespace

PoseParameterization resolve_pose_parameters(const Skeleton& skeleton,
                                             const std::vector<std::string>& free_bones,
                                             const std::vector<PoseParameter>& parameters) {
  PoseParameterization z;
  resolve_groups(skeleton, free_bones, parameters, z);
  const int nb = skeleton.bone_count();
  z.bone_axis.assign(nb, Eigen::Vector3d::Zero());
  for (int b = 0; b < nb; ++b) {
    const Eigen::Vector3d d = (skeleton.tails.row(b) - skeleton.heads.row(b)).transpose();
    if (d.norm() > 1e-12) z.bone_axis[b] = d.normalized();
  }
  for (const FittedParameter& prm : z.params)
    if (prm.one_dof())
      for (int b : prm.bones)
        if (z.bone_axis[b].squaredNorm() == 0)
          throw InputError("pose fit: twist or curl bone '" + skeleton.names[b] +
                           "' has zero length");
  z.dof_axis = z.bone_axis;
  z.hand_of.assign(nb, -1);
  for (const FittedParameter& prm : z.params) {
    if (!prm.curl && !prm.tuck) continue;
    for (int b : prm.bones) {
      const int w = hand_wrist(skeleton, b);
      const auto [normal, centre] = palm_normal(skeleton, b, w);
      if (prm.tuck) {
        // About the palm normal, signed so that the bone's tail moves towards the palm's centre
        // (across the palm; the same sense on either hand).
        const Eigen::Vector3d tail = skeleton.tails.row(b).transpose();
        const Eigen::Vector3d head = skeleton.heads.row(b).transpose();
        const Eigen::Vector3d move = normal.cross(tail - head);
        z.dof_axis[b] = move.dot(centre - tail) >= 0 ? normal : Eigen::Vector3d(-normal);
        continue;
      }
      z.hand_of[b] = w;
      const Eigen::Vector3d axis = z.bone_axis[b].cross(normal);
      if (axis.norm() < 1e-6)
        throw InputError("pose fit: cannot find a curl axis for bone '" + skeleton.names[b] +
                         "' (expected a hand of several bones below its wrist)");
      z.dof_axis[b] = axis.normalized();
    }
  }
  return z;
}

Eigen::Matrix3d parameter_rotation(const PoseParameterization& z, const PoseUnknowns& u, int k,
                                   int b) {
  return z.params[k].one_dof() ? rotation_from_vector(u.joints[k][0] * z.dof_axis[b])
                               : rotation_from_vector(u.joints[k]);
}

Pose pose_of(const PoseParameterization& z, const PoseUnknowns& u, int bone_count) {
  Pose p = Pose::rest(bone_count);
  p.rotations[0] = rotation_from_vector(u.root);
  p.root_translation = u.translation;
  for (int k = 0; k < z.count(); ++k)
    for (int b : z.params[k].bones) p.rotations[b] = parameter_rotation(z, u, k, b);
  return p;
}

}  // namespace bodymodel
