// `bodymodel skin fit`: fit an SSD, Animation Space or MWE rig to example poses and write it as
// .npz (keys in skinning/rig_io.h).
#include <fmt/format.h>

#include <memory>

#include "core/io/libigl_formats.h"
#include "core/io/mesh_io.h"
#include "skinning/rig_io.h"
#include "skinning/sequence_evaluation.h"
#include "tools/console.h"
#include "tools/verb.h"
#include "tools/verbs/skinning_common.h"

namespace bodymodel::cli {
namespace {

struct FitArgs {
  std::string rest, poses, transforms, method = "mwe", out = "rig.npz";
  int bones = 0, max_influences = 4;
  double as_ridge = AnimationSpaceFitOptions{}.ridge, mwe_s = MweFitOptions{}.ridge_scale;
  int mwe_components = MweFitOptions{}.components;
};

// Per-pose transforms: a folder of <pose name>.Tmat files, or a libigl animation DMAT with one
// column per pose (poses in sorted file order).
std::vector<BoneTransforms> read_pose_transforms(const std::filesystem::path& T, const MeshSequence& seq) {
  std::vector<BoneTransforms> out;
  if (std::filesystem::is_directory(T)) {
    for (const auto& name : seq.names) {
      const auto f = T / (name + ".Tmat");
      if (!std::filesystem::exists(f))
        throw InputError(f.string() + ": missing bone transforms for pose '" + name + "'");
      out.push_back(read_tmat(f));
    }
  } else {
    out = read_transform_animation(T);
    if (out.size() != seq.frames.size())
      throw InputError(T.string() + ": " + std::to_string(out.size()) + " transform frames for " +
                       std::to_string(seq.frames.size()) + " poses in the folder");
  }
  for (size_t p = 1; p < out.size(); ++p)
    if (out[p].size() != out[0].size())
      throw InputError(T.string() + ": pose " + seq.names[p] + " has " + std::to_string(out[p].size()) +
                       " bones, the first pose " + std::to_string(out[0].size()));
  return out;
}

void run_fit(const FitArgs& a) {
  const SkinningMethod method = parse_skinning_method(a.method);
  const Mesh rest = read_mesh(a.rest);
  const MeshSequence seq = read_mesh_sequence(a.poses);
  for (size_t p = 0; p < seq.frames.size(); ++p)
    if (seq.frames[p].rows() != rest.V.rows())
      throw InputError(a.poses + "/" + seq.names[p] + ": " + std::to_string(seq.frames[p].rows()) +
                       " vertices, the rest mesh " + a.rest + " has " + std::to_string(rest.V.rows()));
  if (a.transforms.empty() == (a.bones <= 0))
    throw InputError("give exactly one of --transforms (known bone transforms) or --bones N (recover N bones)");
  ProgressBar bar("skin fit");
  auto cb = bar.callback();
  SkinningExamples ex;
  SkinningRig lbs;
  if (!a.transforms.empty()) {
    ex.rest = rest.V;
    ex.poses = seq.frames;
    ex.transforms = read_pose_transforms(a.transforms, seq);
    LbsFitOptions lo;
    lo.max_influences = a.max_influences;
    LbsFitSummary ls;
    lbs = fit_lbs(ex, {}, lo, &ls, [&](double f, std::string_view w) { return cb(0.4 * f, w); });
    info(ls.brief());
  } else {
    // Rest mesh as frame 0 (identity), every pose a training frame.
    std::vector<Eigen::MatrixX3d> frames{rest.V};
    frames.insert(frames.end(), seq.frames.begin(), seq.frames.end());
    std::vector<int> train(frames.size());
    for (size_t i = 0; i < train.size(); ++i) train[i] = static_cast<int>(i);
    SequenceEvaluationOptions opt;
    opt.recovery.bones = a.bones;
    opt.max_influences = a.max_influences;
    const PreparedSequence prep = prepare_skinning_sequence(frames, rest.F, train, opt, {},
        [&](double f, std::string_view w) { return cb(0.6 * f, w); });
    ex = prep.examples;
    lbs = prep.lbs;
    info(prep.recovery.brief());
    info(prep.lbs_summary.brief());
  }
  SkinningRig rig = lbs;
  if (method == SkinningMethod::animation_space) {
    AnimationSpaceFitOptions o;
    o.ridge = a.as_ridge;
    AnimationSpaceFitSummary s;
    rig = fit_animation_space(ex, &lbs, o, &s);
    info(s.brief());
  } else if (method == SkinningMethod::mwe) {
    MweFitOptions o;
    o.ridge_scale = a.mwe_s;
    o.components = a.mwe_components;
    MweFitSummary s;
    rig = fit_mwe(ex, &lbs, o, &s, [&](double f, std::string_view w) { return cb(0.6 + 0.4 * f, w); });
    info(s.brief());
  }
  bar.finish();
  save_rig(a.out, rig, rest.F, ex.transforms);
  info(fmt::format("wrote {} ({} rig, {} vertices, {} bones, ≤{} influences, {} poses)", a.out,
                   skinning_method_name(rig.method), rig.vertex_count(), rig.bone_count, rig.max_influences(),
                   ex.pose_count()));
}

}  // namespace

BODYMODEL_VERB(add_skin_fit_verb) {
  CLI::App* skin = skin_group(app);
  auto* cmd = skin->add_subcommand("fit", "Fit an SSD, Animation Space or MWE rig to example poses (.npz out)");
  auto a = std::make_shared<FitArgs>();
  cmd->add_option("--rest", a->rest, "Rest mesh (.obj/.ply)")->required();
  cmd->add_option("--poses", a->poses, "Folder of example poses (.obj/.ply, same vertex order)")->required();
  cmd->add_option("--transforms", a->transforms,
                  "Bone transforms: a folder of <pose>.Tmat files or a libigl animation .dmat (one column per pose)");
  cmd->add_option("--bones", a->bones, "Recover this many bones from the poses instead (no skeleton)");
  cmd->add_option("--method", a->method, "ssd, as or mwe");
  cmd->add_option("--max-influences", a->max_influences, "Influence bones per vertex");
  cmd->add_option("--as-ridge", a->as_ridge, "Animation Space ridge λ (relative)");
  cmd->add_option("--mwe-s", a->mwe_s, "MWE ridge scale s, relative to the diagonal (λ_h = s·d⁴/σ²(c_h))");
  cmd->add_option("--mwe-components", a->mwe_components, "MWE principal components kept (0 = all with variance)");
  cmd->add_option("--out", a->out, "Output rig (.npz)");
  cmd->callback([a] { run_fit(*a); });
}

}  // namespace bodymodel::cli
