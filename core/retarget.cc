#include "core/retarget.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <set>

#include "core/error.h"
#include "core/io/atomic_write.h"

namespace bodymodel {
namespace fs = std::filesystem;

namespace {

bool starts_with(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

// Chains fixed to the hips (root, pelvis) and the small finger/toe chains get no rest
// correction of their own: their source bones do not correspond to the hm08 bones in
// direction (a Poser "buttock" points down and back, the hm08 pelvis bone sideways).
bool corrects_rest(const std::vector<std::string>& targets) {
  for (const auto& t : targets)
    if (t == "root" || starts_with(t, "pelvis") || starts_with(t, "finger") ||
        starts_with(t, "toe") || starts_with(t, "metacarpal"))
      return false;
  return true;
}

bool is_limb_chain(const std::vector<std::string>& targets) {
  for (const auto& t : targets)
    if (!(starts_with(t, "upperarm") || starts_with(t, "lowerarm") || starts_with(t, "wrist") ||
          starts_with(t, "upperleg") || starts_with(t, "lowerleg") || starts_with(t, "foot")))
      return false;
  return !targets.empty();
}

std::string clip_name(const BvhMotion& clip) {
  return clip.source.empty() ? std::string("BVH clip") : "BVH '" + clip.source + "'";
}

std::string joined(const std::vector<std::string>& names, size_t at_most = 8) {
  std::string s;
  for (size_t i = 0; i < names.size() && i < at_most; ++i) s += (i ? ", " : "") + names[i];
  if (names.size() > at_most) s += ", ... (" + std::to_string(names.size()) + " in all)";
  return s;
}

void check_unique_joint_names(const BvhMotion& clip) {
  std::set<std::string> seen, twice;
  for (const auto& j : clip.joints)
    if (!seen.insert(j.name).second) twice.insert(j.name);
  if (!twice.empty())
    throw InputError(clip_name(clip) + ": two joints are named '" + *twice.begin() +
                     "' (a joint name must be unique; which one would drive the bone?)");
}

// Largest rotation of joint j over the clip's frames, degrees.
double largest_rotation_deg(const BvhMotion& clip, int j) {
  bool rotates = false;
  for (BvhChannel c : clip.joints[j].channels) rotates |= bvh_is_rotation(c);
  if (!rotates) return 0;
  double worst = 0;
  for (int f = 0; f < clip.frame_count(); ++f) {
    const double c = std::clamp((bvh_joint_rotation(clip, f, j).trace() - 1) / 2, -1.0, 1.0);
    worst = std::max(worst, std::acos(c) * 180 / 3.14159265358979323846);
  }
  return worst;
}

// Bones the retarget chains of fingers, toes and eyes drive (a clip may lack their joints).
bool is_extremity(const std::string& bone) {
  return starts_with(bone, "finger") || starts_with(bone, "toe") || starts_with(bone, "metacarpal") ||
         starts_with(bone, "eye");
}

}  // namespace

void check_clip_by_bone_name(const BvhMotion& clip, const Skeleton& skeleton) {
  check_unique_joint_names(clip);
  std::vector<std::string> dropped;
  for (int j = 0; j < static_cast<int>(clip.joints.size()); ++j) {
    const std::string& name = clip.joints[j].name;
    const int b = skeleton.find(name);
    if (b < 0) {
      if (largest_rotation_deg(clip, j) > 0.01) dropped.push_back(name);
      continue;
    }
    // The nearest joint above it that names a bone must name one of the bone's ancestors.
    int a = clip.joints[j].parent;
    while (a >= 0 && skeleton.find(clip.joints[a].name) < 0) a = clip.joints[a].parent;
    if (a < 0) continue;
    const int ab = skeleton.find(clip.joints[a].name);
    int p = skeleton.parents[b];
    while (p >= 0 && p != ab) p = skeleton.parents[p];
    if (p != ab)
      throw InputError(clip_name(clip) + ": joint '" + name + "' hangs below '" + clip.joints[a].name +
                       "' in the clip, but in the skeleton bone '" + name + "' is not below '" +
                       clip.joints[a].name + "' (a renamed joint?); its rotation would turn the wrong part");
  }
  if (!dropped.empty())
    throw InputError(clip_name(clip) + ": " + std::to_string(dropped.size()) + " rotating joint" +
                     (dropped.size() == 1 ? " names" : "s name") + " no bone of the skeleton: " + joined(dropped) +
                     " (renamed?); their motion would be lost");
}

RetargetOptions RetargetOptions::for_animation() {
  RetargetOptions o;
  o.first_bone_twist = 0.5;
  o.drive_fingers = false;
  return o;
}

RetargetMap RetargetMap::poser_cmu() {
  RetargetMap m;
  auto add = [&](std::string source, std::vector<std::string> targets) {
    const bool correct = corrects_rest(targets);
    m.entries.push_back({std::move(source), std::move(targets), correct});
  };
  add("hip", {"root"});
  // spine05 is the top of the pelvis: it moves with the hips, as in rig/cmu_mb.mhskel (Hips →
  // root, spine05); the abdomen bends the lumbar bones above it.
  add("abdomen", {"spine04", "spine03"});
  add("chest", {"spine02", "spine01"});
  add("neck", {"neck01", "neck02", "neck03"});
  add("head", {"head"});
  for (const char* side : {"l", "r"}) {
    const std::string s = side, S = s == "l" ? ".L" : ".R";
    add(s + "Collar", {"clavicle" + S, "shoulder01" + S});
    add(s + "Shldr", {"upperarm01" + S, "upperarm02" + S});
    add(s + "ForeArm", {"lowerarm01" + S, "lowerarm02" + S});
    add(s + "Hand", {"wrist" + S});
    add(s + "Buttock", {"pelvis" + S});
    add(s + "Thigh", {"upperleg01" + S, "upperleg02" + S});
    add(s + "Shin", {"lowerleg01" + S, "lowerleg02" + S});
    add(s + "Foot", {"foot" + S});
  }
  return m;
}

RetargetMap RetargetMap::from_mhskel(const fs::path& mhskel) {
  nlohmann::ordered_json j;
  try {
    j = nlohmann::ordered_json::parse(read_text_file(mhskel));
  } catch (const nlohmann::json::exception& e) {
    throw InputError("skeleton '" + mhskel.string() + "' is not valid JSON: " + e.what());
  }
  if (!j.contains("bones") || !j["bones"].is_object())
    throw InputError("skeleton '" + mhskel.string() + "': expected an object 'bones'");
  // Rig names that the cgspeed BVH spells differently (README §7.2).
  const std::vector<std::pair<std::string, std::string>> aliases{
      {"LeftHandFinger1", "LeftHandIndex1"}, {"RightHandFinger1", "RightHandIndex1"}};
  RetargetMap m;
  std::set<std::string> claimed;
  for (auto it = j["bones"].begin(); it != j["bones"].end(); ++it) {
    const auto& b = it.value();
    Entry e;
    e.source = it.key();
    for (const auto& [rig, bvh] : aliases)
      if (e.source == rig) e.source = bvh;
    if (b.contains("reference") && b["reference"].is_array())
      for (const auto& r : b["reference"])
        if (r.is_string() && claimed.insert(r.get<std::string>()).second)
          e.targets.push_back(r.get<std::string>());
    if (e.targets.empty()) continue;
    e.correct_rest = corrects_rest(e.targets);
    m.entries.push_back(std::move(e));
  }
  return m;
}

RetargetMap RetargetMap::for_clip(const BvhMotion& clip, const fs::path& makehuman_dir) {
  auto matched = [&](const RetargetMap& m) {
    int n = 0;
    for (const auto& e : m.entries) n += clip.find(e.source) >= 0;
    return static_cast<double>(n) / std::max<size_t>(1, m.entries.size());
  };
  RetargetMap poser = poser_cmu();
  const fs::path rig = makehuman_dir / "rig" / "cmu_mb.mhskel";
  std::error_code ec;
  RetargetMap cmu = fs::exists(rig, ec) ? from_mhskel(rig) : RetargetMap{};
  const double fp = matched(poser), fc = matched(cmu);
  if (std::max(fp, fc) < 0.5)
    throw InputError("cannot retarget a BVH with root joint '" +
                     (clip.joints.empty() ? std::string("?") : clip.joints[0].name) +
                     "': its joint names match neither the MakeHuman default skeleton, the "
                     "Poser/DAZ CMU names (hip, abdomen, lThigh, ...) nor rig/cmu_mb.mhskel "
                     "(Hips, LeftUpLeg, ...)");
  return fp >= fc ? poser : cmu;
}

Retargeter::Retargeter(const BvhMotion& clip, const Skeleton& target, const RetargetMap& map,
                       const RetargetOptions& options)
    : clip_(clip), target_(target), options_(options) {
  clip_.validate();
  target_.validate();
  // A renamed joint leaves its map entry without a source, and the bones it drives at rest.
  check_unique_joint_names(clip_);
  {
    std::vector<std::string> missing, drives;
    for (const auto& e : map.entries) {
      if (clip_.find(e.source) >= 0) continue;
      for (const auto& t : e.targets)
        if (!is_extremity(t) && target_.find(t) >= 0) {
          missing.push_back(e.source);
          if (drives.empty()) drives = e.targets;
          break;
        }
    }
    if (!missing.empty()) {
      std::vector<std::string> unknown;
      std::set<std::string> sources;
      for (const auto& e : map.entries) sources.insert(e.source);
      for (const auto& j : clip_.joints)
        if (!sources.count(j.name)) unknown.push_back(j.name);
      throw InputError(clip_name(clip_) + ": the retarget map needs " +
                       (missing.size() == 1 ? "joint '" + missing[0] + "' (it drives " + joined(drives) + ")"
                                            : "joints " + joined(missing) + " (the first drives " + joined(drives) + ")") +
                       ", which the clip lacks" +
                       (unknown.empty() ? std::string() : "; joints the map does not know: " + joined(unknown)) +
                       " (renamed joints?)");
    }
  }
  C_ = bvh_axis_conversion(options.up_axis ? *options.up_axis : guess_bvh_up_axis(clip_));
  const int nj = static_cast<int>(clip_.joints.size());
  const int nb = target_.bone_count();
  driver_.assign(nb, -1);
  spread_.assign(nb, 0);
  std::vector<const RetargetMap::Entry*> entry_of(nj, nullptr);
  for (const auto& e : map.entries) {
    const int j = clip_.find(e.source);
    if (j < 0) {
      unmatched_.push_back(e.source);
      continue;
    }
    if (entry_of[j]) continue;  // first entry wins
    std::vector<std::string> present;
    for (const auto& t : e.targets) {
      if (!options.drive_fingers && (starts_with(t, "finger") || starts_with(t, "metacarpal"))) continue;
      const int b = target_.find(t);
      if (b >= 0 && driver_[b] < 0) {
        driver_[b] = j;
        present.push_back(t);
      }
    }
    if (!present.empty()) entry_of[j] = &e;
    // Spine and neck chains of consecutive bones share the bend.
    bool spine = present.size() >= 2;
    for (size_t i = 0; i < present.size() && spine; ++i) {
      spine = starts_with(present[i], "spine") || starts_with(present[i], "neck");
      if (i > 0) spine = spine && target_.parents[target_.find(present[i])] == target_.find(present[i - 1]);
    }
    if (spine)
      for (const auto& t : present) spread_[target_.find(t)] = static_cast<int>(present.size());
  }

  // Limb two-bone chains whose twist is split (RetargetOptions::first_bone_twist).
  twist_child_.assign(nb, -1);
  for (const char* pair : {"upperarm01", "lowerarm01", "upperleg01", "lowerleg01"})
    for (const char* side : {".L", ".R"}) {
      std::string first = std::string(pair) + side, second = first;
      second[second.size() - 3] = '2';
      const int b1 = target_.find(first), b2 = target_.find(second);
      if (b1 >= 0 && b2 >= 0 && target_.parents[b2] == b1 && driver_[b1] >= 0 && driver_[b2] == driver_[b1])
        twist_child_[b1] = b2;
    }

  // Rest positions of the source joints (file units, hm08 axes).
  const Eigen::MatrixX3d P = (clip_.rest_positions() * C_.transpose()).eval();
  auto chain_direction = [&](const RetargetMap::Entry& e) -> Eigen::Vector3d {
    int first = -1, last = -1;
    for (const auto& t : e.targets) {
      const int b = target_.find(t);
      if (b < 0) continue;
      if (first < 0) first = b;
      last = b;
    }
    if (first < 0) return Eigen::Vector3d::Zero();
    return (target_.tails.row(last) - target_.heads.row(first)).transpose();
  };
  // Rest correction per source joint, parents first (joints are stored depth-first).
  correction_.assign(nj, Eigen::Matrix3d::Identity());
  for (int j = 0; j < nj; ++j) {
    const int parent = clip_.joints[j].parent;
    Eigen::Matrix3d A = parent >= 0 ? correction_[parent] : Eigen::Matrix3d::Identity();
    const RetargetMap::Entry* e = entry_of[j];
    const bool correct = e && e->correct_rest &&
                         (options.rest_correction == RetargetOptions::RestCorrection::all_chains ||
                          is_limb_chain(e->targets));
    if (correct) {
      const Eigen::Vector3d dt = chain_direction(*e);
      // Source direction: towards the mapped child best aligned with the target chain, or
      // the End Site of a leaf joint; zero-length offsets carry no direction.
      Eigen::Vector3d best = Eigen::Vector3d::Zero();
      double best_cos = -2;
      bool has_child = false;
      for (int c = j + 1; c < nj; ++c) {
        if (clip_.joints[c].parent != j) continue;
        has_child = true;
        if (!entry_of[c]) continue;
        const Eigen::Vector3d ds = (P.row(c) - P.row(j)).transpose();
        if (ds.norm() < 1e-9 || dt.norm() < 1e-9) continue;
        const double cs = ds.normalized().dot(dt.normalized());
        if (cs > best_cos) best_cos = cs, best = ds;
      }
      if (!has_child && clip_.joints[j].end_site) best = C_ * *clip_.joints[j].end_site;
      if (best.norm() > 1e-9 && dt.norm() > 1e-9)
        A = Eigen::Quaterniond::FromTwoVectors(dt, best).toRotationMatrix();
    }
    correction_[j] = A;
  }

  // Translation scale: hm08 thigh+shin (left) over the source's mapped thigh+shin.
  double target_len = 0, source_len = 0;
  for (const char* bone : {"upperleg01.L", "upperleg02.L", "lowerleg01.L", "lowerleg02.L"}) {
    const int b = target_.find(bone);
    if (b >= 0) target_len += (target_.tails.row(b) - target_.heads.row(b)).norm();
  }
  std::set<int> leg_joints;
  for (const char* bone : {"upperleg02.L", "lowerleg02.L"}) {
    const int b = target_.find(bone);
    if (b >= 0 && driver_[b] >= 0) leg_joints.insert(driver_[b]);
  }
  for (int j : leg_joints)
    for (int c = j + 1; c < nj; ++c)
      if (clip_.joints[c].parent == j) {
        source_len += (P.row(c) - P.row(j)).norm();
        break;
      }
  scale_ = (leg_joints.size() == 2 && source_len > 0 && target_len > 0) ? target_len / source_len
                                                                       : 1.0;
  // Rest hip height above the lowest rest joint or End Site (hm08 axes, file units).
  double lowest = P.col(1).minCoeff();
  for (int j = 0; j < nj; ++j)
    if (clip_.joints[j].end_site)
      lowest = std::min(lowest, P(j, 1) + (C_ * *clip_.joints[j].end_site).y());
  rest_hip_height_ = P(0, 1) - lowest;
  if (clip_.frame_count() > 0) start_ = bvh_root_position(clip_, 0);
}

int Retargeter::driven_bone_count() const {
  return static_cast<int>(std::count_if(driver_.begin(), driver_.end(), [](int d) { return d >= 0; }));
}

Pose Retargeter::pose(int frame) const {
  if (frame < 0 || frame >= clip_.frame_count())
    throw InputError("retarget: frame " + std::to_string(frame) + " does not exist (the clip has " +
                     std::to_string(clip_.frame_count()) + " frames)");
  const int nj = static_cast<int>(clip_.joints.size());
  // Source world rotations in hm08 axes.
  std::vector<Eigen::Matrix3d> G(nj);
  for (int j = 0; j < nj; ++j) {
    const Eigen::Matrix3d R = C_ * bvh_joint_rotation(clip_, frame, j) * C_.transpose();
    const int p = clip_.joints[j].parent;
    G[j] = p >= 0 ? Eigen::Matrix3d(G[p] * R) : R;
  }
  // Target world rotations: driven bones follow their source, others their parent.
  const int nb = target_.bone_count();
  std::vector<Eigen::Matrix3d> Q(nb);
  Pose pose = Pose::rest(nb);
  for (int b = 0; b < nb; ++b) {
    const int p = target_.parents[b];
    const int j = driver_[b];
    if (j >= 0) {
      const Eigen::Matrix3d Qp = p >= 0 ? Q[p] : Eigen::Matrix3d::Identity();
      if (spread_[b] > 0 && p >= 0 && driver_[p] == j) {
        // Later bone of a shared chain: the same part of the bend as the first.
        pose.rotations[b] = pose.rotations[p];
        Q[b] = Qp * pose.rotations[b];
      } else if (spread_[b] > 0) {
        const Eigen::Quaterniond total(Eigen::Matrix3d(Qp.transpose() * G[j] * correction_[j]));
        pose.rotations[b] = Eigen::Quaterniond::Identity().slerp(1.0 / spread_[b], total).toRotationMatrix();
        Q[b] = Qp * pose.rotations[b];
      } else {
        Q[b] = G[j] * correction_[j];
        pose.rotations[b] = Qp.transpose() * Q[b];
        if (twist_child_[b] >= 0 && options_.first_bone_twist < 1) {
          // First bone of a limb's two-bone chain: swing and part of the twist (the second
          // bone, driven by the same joint, then takes the rest: its world rotation is
          // unchanged).
          const Eigen::Vector3d a = (target_.tails.row(b) - target_.heads.row(b)).transpose().normalized();
          const Eigen::Quaterniond q(pose.rotations[b]);
          Eigen::Quaterniond t(q.w(), 0, 0, 0);
          t.vec() = q.vec().dot(a) * a;
          if (t.norm() > 1e-12) {
            t.normalize();
            const Eigen::Quaterniond s = q * t.conjugate();
            const Eigen::Quaterniond tf = Eigen::Quaterniond::Identity().slerp(options_.first_bone_twist, t);
            pose.rotations[b] = (s * tf).normalized().toRotationMatrix();
            Q[b] = Qp * pose.rotations[b];
          }
        }
      }
    } else {
      Q[b] = p >= 0 ? Q[p] : Eigen::Matrix3d::Identity();
    }
  }
  if (options_.apply_root_translation) {
    bool has_position = false;
    for (BvhChannel c : clip_.joints[0].channels) has_position |= !bvh_is_rotation(c);
    if (has_position) {
      Eigen::Vector3d p = C_ * bvh_root_position(clip_, frame);
      const Eigen::Vector3d p0 = C_ * start_;
      Eigen::Vector3d ref = C_ * clip_.joints[0].offset;
      if (options_.start_at_origin) ref.x() = p0.x(), ref.z() = p0.z();
      // Standing in the rest pose puts the root at its rest height above the floor (y = 0).
      ref.y() = rest_hip_height_;
      pose.root_translation = scale_ * (p - ref);
    }
  }
  return pose;
}

std::vector<Pose> Retargeter::all_poses() const {
  std::vector<Pose> out;
  out.reserve(frame_count());
  for (int f = 0; f < frame_count(); ++f) out.push_back(pose(f));
  return out;
}

std::vector<Pose> poses_from_bvh(const BvhMotion& clip, const Skeleton& skeleton,
                                 const fs::path& makehuman_dir, bool with_translation) {
  int named = 0;
  for (const auto& j : clip.joints) named += skeleton.find(j.name) >= 0;
  std::vector<Pose> out;
  if (named * 2 >= skeleton.bone_count()) {
    check_clip_by_bone_name(clip, skeleton);
    BvhPoseOptions o;
    o.apply_root_translation = with_translation;
    for (int f = 0; f < clip.frame_count(); ++f) out.push_back(bvh_frame_to_pose(clip, f, skeleton, o));
    return out;
  }
  RetargetOptions o;
  o.apply_root_translation = with_translation;
  return Retargeter(clip, skeleton, RetargetMap::for_clip(clip, makehuman_dir), o).all_poses();
}

}  // namespace bodymodel
