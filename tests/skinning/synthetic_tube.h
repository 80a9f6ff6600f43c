// A small synthetic rig for skinning tests: a closed tube along +x (length 3, radius 0.3) with a
// chain of three bones ([0,1], [1,2], [2,3]) and smooth LBS weights, posed by random joint
// rotations (seeded).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <vector>

#include "core/skeleton.h"
#include "skinning/skinning_examples.h"
#include "skinning/skinning_rig.h"

namespace bodymodel::testing {

struct SyntheticTube {
  Eigen::MatrixX3d V;    // rest
  Eigen::MatrixX3i F;
  Eigen::MatrixXd W;     // #V by 3 true weights
};

inline SyntheticTube make_tube(int rings = 31, int segments = 16) {
  SyntheticTube t;
  t.V.resize(rings * segments + 2, 3);
  for (int r = 0; r < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      const double a = 2 * M_PI * s / segments, x = 3.0 * r / (rings - 1);
      t.V.row(r * segments + s) << x, 0.3 * std::cos(a), 0.3 * std::sin(a);
    }
  const int c0 = rings * segments, c1 = c0 + 1;
  t.V.row(c0) << 0, 0, 0;
  t.V.row(c1) << 3, 0, 0;
  std::vector<Eigen::Vector3i> tris;
  for (int r = 0; r + 1 < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      const int a = r * segments + s, b = r * segments + (s + 1) % segments;
      const int c = a + segments, d = b + segments;
      tris.emplace_back(a, b, d);
      tris.emplace_back(a, d, c);
    }
  for (int s = 0; s < segments; ++s) {
    tris.emplace_back(c0, (s + 1) % segments, s);
    const int base = (rings - 1) * segments;
    tris.emplace_back(c1, base + s, base + (s + 1) % segments);
  }
  t.F.resize(static_cast<Eigen::Index>(tris.size()), 3);
  for (size_t i = 0; i < tris.size(); ++i) t.F.row(static_cast<Eigen::Index>(i)) = tris[i];
  // Smooth weights: bone b's hat centred at b + 0.5, blending over ±0.35 around each joint.
  t.W = Eigen::MatrixXd::Zero(t.V.rows(), 3);
  for (Eigen::Index i = 0; i < t.V.rows(); ++i) {
    const double x = t.V(i, 0);
    auto ramp = [](double u) { return std::clamp(u, 0.0, 1.0); };
    const double s1 = ramp((x - 0.65) / 0.7), s2 = ramp((x - 1.65) / 0.7);   // smoothstep-ish
    t.W(i, 0) = 1 - s1;
    t.W(i, 1) = s1 * (1 - s2);
    t.W(i, 2) = s1 * s2;
  }
  return t;
}

// Random chain pose: bone 0 rotates about the origin, bones 1 and 2 about their joints at x = 1, 2
// (angles up to max_angle), plus a translation; `fixed_root` keeps bone 0 at rest (a character
// whose limbs move, the way MWE is meant to be used: its weights are tied to model axes).
inline BoneTransforms random_chain_pose(std::mt19937& rng, double max_angle = 1.0,
                                        bool fixed_root = false) {
  std::uniform_real_distribution<double> u(-1, 1);
  auto rot = [&] {
    Eigen::Vector3d axis(u(rng), u(rng), u(rng));
    axis.normalize();
    return Eigen::AngleAxisd(max_angle * u(rng), axis).toRotationMatrix();
  };
  BoneTransforms M(3, Eigen::Affine3d::Identity());
  M[0].linear() = rot();
  M[0].translation() = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.3;
  if (fixed_root) M[0] = Eigen::Affine3d::Identity();
  for (int b = 1; b < 3; ++b) {
    Eigen::Affine3d local = Eigen::Affine3d::Identity();
    const Eigen::Vector3d joint(b, 0, 0);
    local.linear() = rot();
    local.translation() = joint - local.linear() * joint;
    M[static_cast<size_t>(b)] = M[static_cast<size_t>(b - 1)] * local;
  }
  return M;
}

// A true Animation Space rig on the tube: SSD weights times ṽ plus a random perturbation of each
// used p_k (normal, `sigma` for x y z, 0.3 sigma for w).
inline SkinningRig animation_space_truth(const SyntheticTube& t, std::mt19937& rng, double sigma) {
  const SkinningRig truth = lbs_rig_from_weights(t.V, t.W, 3, 0.0);
  SkinningRig as = truth;
  as.method = SkinningMethod::animation_space;
  as.coefficients.resize(t.V.rows(), 12);
  std::normal_distribution<double> g(0, sigma);
  for (Eigen::Index i = 0; i < t.V.rows(); ++i)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector4d v(t.V(i, 0), t.V(i, 1), t.V(i, 2), 1);
      Eigen::Vector4d p = truth.coefficients(i, k) * v;
      if (truth.coefficients(i, k) > 0) p += Eigen::Vector4d(g(rng), g(rng), g(rng), 0.3 * g(rng));
      as.coefficients.row(i).segment<4>(4 * k) = p.transpose();
    }
  return as;
}

// Examples posed by the tube's true LBS rig.
inline SkinningExamples lbs_examples(const SyntheticTube& t, int poses, unsigned seed, bool fixed_root = false) {
  std::mt19937 rng(seed);
  const SkinningRig truth = lbs_rig_from_weights(t.V, t.W, 3, 0.0);
  SkinningExamples ex;
  ex.rest = t.V;
  for (int p = 0; p < poses; ++p) {
    ex.transforms.push_back(random_chain_pose(rng, 1.0, fixed_root));
    ex.poses.push_back(evaluate_rig(truth, ex.transforms.back()));
  }
  return ex;
}

// A non-linear "bulge" on top of LBS that no SSD weights reproduce: the skin swells along the
// radial direction with the sine of the elbow's rotation angle. The root stays at rest.
inline SkinningExamples bulging_examples(const SyntheticTube& t, int poses, unsigned seed) {
  SkinningExamples ex = lbs_examples(t, poses, seed, true);
  for (int p = 0; p < poses; ++p) {
    const Eigen::Matrix3d rel = ex.transforms[p][0].linear().transpose() * ex.transforms[p][1].linear();
    const double angle = Eigen::AngleAxisd(rel).angle();
    for (Eigen::Index i = 0; i < t.V.rows(); ++i) {
      const double x = t.V(i, 0);
      const double bump = 0.08 * std::sin(angle) * std::exp(-4 * (x - 1) * (x - 1));
      Eigen::Vector3d radial(0, t.V(i, 1), t.V(i, 2));
      ex.poses[p].row(i) += (ex.transforms[p][1].linear() * radial * bump / 0.3).transpose();
    }
  }
  return ex;
}

}  // namespace bodymodel::testing
