// `bodymodel skin candy-wrapper`: Jacka-style "twist" and "arm bend" cases on the libigl arm rig
// ($BODYMODEL_DATA/animations/arm-rig, its README "arm-rig"; docs/data.md). Reference frames come
// from dual-quaternion skinning with the true weights; SSD (weights fitted to the reference frames
// with the true transforms), Animation Space and MWE are fitted to a few frames and evaluated on
// all of them.
#include <fmt/format.h>

#include <Eigen/Geometry>
#include <memory>

#include "core/data_path.h"
#include "core/geometry.h"
#include "core/io/atomic_write.h"
#include "core/io/libigl_formats.h"
#include "core/io/mesh_io.h"
#include "skinning/dual_quaternion_skinning.h"
#include "skinning/fit_animation_space.h"
#include "skinning/fit_lbs.h"
#include "skinning/fit_mwe.h"
#include "skinning/skinning_error.h"
#include "tools/console.h"
#include "tools/verb.h"
#include "tools/verbs/skin_common.h"

namespace bodymodel::cli {
namespace {

// libigl forward_kinematics with relative rotations dQ about each bone's start joint.
BoneTransforms chain_pose(const TgfGraph& g, const std::vector<Eigen::Quaterniond>& dQ) {
  const int B = static_cast<int>(g.E.rows());
  std::vector<int> parent(static_cast<size_t>(B), -1);
  for (int b = 0; b < B; ++b)
    for (int p = 0; p < B; ++p)
      if (g.E(p, 1) == g.E(b, 0)) parent[static_cast<size_t>(b)] = p;
  std::vector<Eigen::Quaterniond> vQ(static_cast<size_t>(B));
  std::vector<Eigen::Vector3d> vT(static_cast<size_t>(B));
  std::vector<bool> done(static_cast<size_t>(B), false);
  BoneTransforms M(static_cast<size_t>(B));
  for (int pass = 0; pass < B; ++pass)
    for (int b = 0; b < B; ++b) {
      const int p = parent[static_cast<size_t>(b)];
      if (done[static_cast<size_t>(b)] || (p >= 0 && !done[static_cast<size_t>(p)])) continue;
      const Eigen::Vector3d r = g.C.row(g.E(b, 0)).transpose();
      if (p < 0) {
        vQ[b] = dQ[b];
        vT[b] = r - (dQ[b] * r);
      } else {
        vQ[b] = vQ[p] * dQ[b];
        vT[b] = vT[p] - (vQ[b] * r) + (vQ[p] * r);
      }
      done[b] = true;
      M[b] = Eigen::Affine3d::Identity();
      M[b].linear() = vQ[b].toRotationMatrix();
      M[b].translation() = vT[b];
    }
  return M;
}

struct Case {
  std::string name;
  std::vector<double> angles;     // parameter per frame
  std::vector<int> train;         // indices into angles
};

void run_candy(const std::string& out_dir) {
  const auto dir = data_file("animations/arm-rig");
  const Mesh arm = read_mesh(dir / "arm.obj");
  const TgfGraph g = read_tgf(dir / "arm.tgf");
  const Eigen::MatrixXd W = read_dmat(dir / "arm-weights.dmat");
  if (W.rows() != arm.V.rows() || W.cols() != g.E.rows())
    throw InputError((dir / "arm-weights.dmat").string() + ": weights do not match the mesh and skeleton");
  const int B = static_cast<int>(g.E.rows());
  auto q_rest = [&](int b) {
    const Eigen::Vector3d d = (g.C.row(g.E(b, 1)) - g.C.row(g.E(b, 0))).transpose();
    return Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitX(), d);
  };
  const Eigen::Quaterniond q2 = q_rest(2);
  auto pose_for = [&](const std::string& kind, double a) {
    std::vector<Eigen::Quaterniond> dQ(static_cast<size_t>(B), Eigen::Quaterniond::Identity());
    const Eigen::Quaterniond R = kind == "twist" ? Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX()))
                                                 : Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()));
    dQ[2] = q2 * R * q2.inverse();
    return chain_pose(g, dQ);
  };
  const SkinningRig truth = lbs_rig_from_weights(arm.V, W, 4, 0.0);
  const double d = bounding_box_diagonal(arm.V);
  std::string md = fmt::format(
      "# Candy-wrapper check on the libigl arm rig\n\nReference: dual-quaternion skinning with the true "
      "weights. Errors against it in the rig's units (bbox diagonal {:.4f}): mean vertex error and mean "
      "geometric deviation (surface), means over vertices of the frames of the split; the last column is the "
      "mean vertex error at the extreme frame (180° twist or −0.7π bend). SSD-true uses the rig's own weights; "
      "the others are fitted with the true transforms.\n\n"
      "| case | method | train frames | mean vertex (train) | mean vertex (unseen) | mean geometric (unseen) | mean vertex at extreme |\n"
      "|---|---|---|---|---|---|---|\n", d);
  std::vector<Case> cases;
  {
    Case t{"twist", {}, {}};
    for (int k = 0; k <= 12; ++k) t.angles.push_back(M_PI * k / 12);   // 0°, 15°, …, 180°
    t.train = {0, 4, 8, 12};                                             // 0°, 60°, 120°, 180°
    cases.push_back(t);
    Case b{"bend", {}, {}};
    for (int k = 0; k <= 12; ++k) b.angles.push_back(-0.7 * M_PI * k / 12);
    b.train = {0, 4, 8, 12};
    cases.push_back(b);
  }
  for (const Case& c : cases) {
    std::vector<BoneTransforms> T;
    std::vector<Eigen::MatrixX3d> ref;
    for (double a : c.angles) {
      T.push_back(pose_for(c.name, a));
      ref.push_back(dual_quaternion_skinning(arm.V, W, T.back()));
    }
    SkinningExamples ex;
    ex.rest = arm.V;
    for (int t : c.train) {
      ex.transforms.push_back(T[static_cast<size_t>(t)]);
      ex.poses.push_back(ref[static_cast<size_t>(t)]);
    }
    LbsFitOptions lo;
    lo.max_influences = 4;
    const SkinningRig ssd = fit_lbs(ex, truth.influences, lo);
    const SkinningRig as = fit_animation_space(ex, &ssd);
    const SkinningRig mwe = fit_mwe(ex, &ssd);
    const std::vector<std::pair<std::string, const SkinningRig*>> rigs{
        {"ssd-true", &truth}, {"ssd", &ssd}, {"as", &as}, {"mwe", &mwe}};
    for (const auto& [name, rig] : rigs) {
      DeviationStats tr, un;
      double extreme = 0;
      for (size_t f = 0; f < c.angles.size(); ++f) {
        const MeshDeviation dev = mesh_deviation(evaluate_rig(*rig, T[f]), ref[f], arm.F);
        const bool is_train = std::find(c.train.begin(), c.train.end(), static_cast<int>(f)) != c.train.end();
        (is_train ? tr : un).add(dev);
        if (f + 1 == c.angles.size()) extreme = dev.vertex.mean();
      }
      md += fmt::format("| {} | {} | {} | {:.6f} | {:.6f} | {:.6f} | {:.6f} |\n", c.name, name, c.train.size(),
                        tr.mean_vertex(), un.mean_vertex(), un.mean_geometric(), extreme);
    }
  }
  ensure_directory(out_dir);
  write_text_file(std::filesystem::path(out_dir) / "candy_wrapper.md", md);
  std::printf("%s", md.c_str());
}

}  // namespace

BODYMODEL_VERB(add_skin_candy_verb) {
  CLI::App* skin = skin_group(app);
  auto* cmd = skin->add_subcommand("candy-wrapper", "Twist and bend of the libigl arm rig against dual-quaternion "
                                                    "skinning: SSD collapse vs fitted AS and MWE");
  auto out = std::make_shared<std::string>("report");
  cmd->add_option("--out", *out, "Report folder (candy_wrapper.md)");
  cmd->callback([out] { run_candy(*out); });
}

}  // namespace bodymodel::cli
