// `bodymodel skin fit`: fit a rig (ssd, dqs, as, mwe, psd, eigenskin, quadratic) to example poses and write it as
// .npz (keys in skinning/rig_io.h).
#include <fmt/format.h>

#include <memory>

#include "core/io/libigl_formats.h"
#include "core/io/mesh_io.h"
#include "skinning/rig_io.h"
#include "skinning/method_comparison.h"
#include "tools/console.h"
#include "tools/verb.h"
#include "tools/verbs/skin_common.h"

namespace bodymodel::cli {
namespace {

struct FitArgs {
  std::string rest, poses, transforms, method = "mwe", out = "rig.npz", cv = "folds:5",
              cv_rule = "min", cv_nesting = cv_nesting_name(SkinCrossValidationOptions{}.nesting);
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

// The training examples and their SSD fit: with known bone maps (--transforms) or bones
// recovered from the rest mesh and the poses (--bones).
PreparedSequence prepare_fit(const FitArgs& a, const Mesh& rest, const MeshSequence& seq,
                             SequenceEvaluationOptions& opt, const ProgressCallback& cb) {
  PreparedSequence prep;
  if (!a.transforms.empty()) {
    SkinningExamples& ex = prep.examples;
    ex.rest = rest.V;
    ex.poses = seq.frames;
    ex.transforms = read_pose_transforms(a.transforms, seq);
    LbsFitOptions lo = opt.lbs;
    lo.max_influences = a.max_influences;
    prep.lbs = fit_lbs(ex, {}, lo, &prep.lbs_summary, [&](double f, std::string_view w) { return cb(0.3 * f, w); });
    info(prep.lbs_summary.brief());
  } else {
    // Rest mesh as frame 0 (identity), every pose a training frame.
    std::vector<Eigen::MatrixX3d> frames{rest.V};
    frames.insert(frames.end(), seq.frames.begin(), seq.frames.end());
    std::vector<int> train(frames.size());
    for (size_t i = 0; i < train.size(); ++i) train[i] = static_cast<int>(i);
    opt.recovery.bones = a.bones;
    prep = prepare_skinning_sequence(frames, rest.F, train, opt, {},
                                     [&](double f, std::string_view w) { return cb(0.3 * f, w); });
    info(prep.recovery.brief());
    info(prep.lbs_summary.brief());
  }
  return prep;
}

// The cross-validator over the example poses, and the settings the method's base takes from it
// (MWE's Animation Space ridge, the pose-space methods' kernel); null without cross-validation.
std::unique_ptr<CrossValidator> make_validator(const FitArgs& a, SkinningModel method, const SkinCrossValidationOptions& cv,
                                               const PreparedSequence& prep, const Mesh& rest,
                                               SequenceEvaluationOptions& opt,
                                               std::vector<std::unique_ptr<ReferenceSurface>>& trees) {
  const SkinningExamples& ex = prep.examples;
  std::vector<const ReferenceSurface*> surfaces;
  std::unique_ptr<CrossValidator> validator;
  if (cv.scheme != CvScheme::none && method != SkinningModel::ssd && method != SkinningModel::dqs) {
    for (const auto& P : ex.poses) {
      trees.push_back(std::make_unique<ReferenceSurface>(P, rest.F));
      surfaces.push_back(trees.back().get());
    }
    LbsFitOptions lo = opt.lbs;
    lo.max_influences = a.max_influences;
    lo.require_rigid = false;
    FoldBoneFitter fold_bones;
    if (cv.nesting == CvNesting::full)
      fold_bones = [&](const std::vector<int>& t, const std::vector<int>& h) {
        return fit_fold_bones(ex, rest.F, t, h, opt);
      };
    validator = std::make_unique<CrossValidator>(ex, lo, cv, surfaces, fold_bones);
    if (method == SkinningModel::mwe)   // the AS base's ridge, chosen the same way
      opt.fit.mwe.base_as_ridge = validator->select(SkinningModel::as, opt.fit).chosen.animation_space.ridge;
    if (method == SkinningModel::eigenskin || method == SkinningModel::quadratic) {   // PSD's pose space
      const PoseSpaceOptions chosen = validator->select(SkinningModel::psd, opt.fit).chosen.pose_space;
      opt.fit.pose_space.kernel_width = chosen.kernel_width;
      opt.fit.pose_space.rbf_ridge = chosen.rbf_ridge;
    }
  }
  return validator;
}

void run_fit(const FitArgs& a) {
  const SkinningModel method = parse_skinning_model(a.method);
  SkinCrossValidationOptions cv = parse_cv_scheme(a.cv, false);
  cv.rule = parse_cv_rule(a.cv_rule);
  cv.nesting = parse_cv_nesting(a.cv_nesting);
  // Given bone maps are not fitted: there is nothing to refit per fold.
  if (!a.transforms.empty()) cv.nesting = CvNesting::weights;
  const Mesh rest = read_mesh(a.rest);
  const MeshSequence seq = read_mesh_sequence(a.poses);
  for (size_t p = 0; p < seq.frames.size(); ++p)
    if (seq.frames[p].rows() != rest.V.rows())
      throw InputError(a.poses + "/" + seq.names[p] + ": " + std::to_string(seq.frames[p].rows()) +
                       " vertices, the rest mesh " + a.rest + " has " + std::to_string(rest.V.rows()));
  if (a.transforms.empty() == (a.bones <= 0))
    throw InputError("give exactly one of --transforms (known bone transforms) or --bones N (recover N bones)");
  if (static_cast<int>(seq.frames.size()) < minimum_examples(method))
    throw InputError(a.poses + ": " + skinning_model_name(method) + " needs at least " +
                     std::to_string(minimum_examples(method)) + " example poses, the folder has " +
                     std::to_string(seq.frames.size()));
  if (cv.scheme != CvScheme::none && method != SkinningModel::ssd && method != SkinningModel::dqs) {
    const int count = static_cast<int>(seq.frames.size()) + (a.bones > 0 ? 1 : 0);   // + the rest frame
    for (const auto& held : cv_folds(count, cv))
      if (count - static_cast<int>(held.size()) < minimum_examples(method))
        throw InputError("--cv " + a.cv + ": a fold leaves " + std::to_string(count - static_cast<int>(held.size())) +
                         " example pose(s), " + skinning_model_name(method) + " needs " +
                         std::to_string(minimum_examples(method)) + " (use fewer folds or --cv none)");
  }
  ProgressBar bar("skin fit");
  auto cb = bar.callback();
  PreparedSequence prep;
  SequenceEvaluationOptions opt;
  opt.max_influences = a.max_influences;
  opt.cv = cv;
  opt.fit.animation_space.ridge = a.as_ridge;
  opt.fit.mwe.ridge_scale = a.mwe_s;
  opt.fit.mwe.components = a.mwe_components;
  prep = prepare_fit(a, rest, seq, opt, cb);
  const SkinningExamples& ex = prep.examples;
  std::vector<std::unique_ptr<ReferenceSurface>> trees;
  const std::unique_ptr<CrossValidator> validator = make_validator(a, method, cv, prep, rest, opt, trees);
  MethodFit mf;
  const FittedModel model = fit_sequence_method(method, prep, opt, validator.get(), &mf,
                                                [&](double f, std::string_view w) { return cb(0.3 + 0.7 * f, w); });
  bar.finish();
  if (!mf.cv.candidates.empty()) info("cross-validation: " + mf.cv.brief());
  info(mf.brief);
  if (model.is_pose_space()) {
    save_pose_space_rig(a.out, model.pose_space, rest.F, ex.transforms);
    info(fmt::format("wrote {} ({} rig over ssd, {} vertices, {} bones, {} example poses)", a.out,
                     skinning_model_name(method), model.pose_space.vertex_count(), model.pose_space.bone_count(),
                     ex.pose_count()));
  } else {
    save_rig(a.out, model.rig, rest.F, ex.transforms);
    info(fmt::format("wrote {} ({} rig, {} vertices, {} bones, ≤{} influences, {} poses)", a.out,
                     skinning_method_name(model.rig.method), model.rig.vertex_count(), model.rig.bone_count,
                     model.rig.max_influences(), ex.pose_count()));
  }
}

}  // namespace

BODYMODEL_VERB(add_skin_fit_verb) {
  CLI::App* skin = skin_group(app);
  auto* cmd = skin->add_subcommand(
      "fit",
      "Fit a rig to example poses (.npz out): ssd, dqs, as, mwe, or the pose-space methods psd,\n"
      "eigenskin and quadratic (a separate rig format, see skinning/rig_io.h). The regularisation of\n"
      "as, mwe and the pose-space methods is chosen by cross-validation over the example poses.\n"
      "  bodymodel skin fit --rest rest.obj --poses poses/ --bones 24 --method mwe --out rig.npz");
  auto a = std::make_shared<FitArgs>();
  cmd->add_option("--rest", a->rest, "Rest mesh (.obj/.ply)")->required();
  cmd->add_option("--poses", a->poses, "Folder of example poses (.obj/.ply, same vertex order)")->required();
  cmd->add_option("--transforms", a->transforms,
                  "Bone transforms: a folder of <pose>.Tmat files or a libigl animation .dmat (one column per pose)");
  cmd->add_option("--bones", a->bones, "Recover this many bones from the poses instead (no skeleton)");
  cmd->add_option("--method", a->method, "ssd, dqs, as, mwe, psd, eigenskin or quadratic")->capture_default_str();
  cmd->add_option("--cv", a->cv, "Cross-validation over the poses: folds:K (interleaved), last:N, none or auto (interleaved folds)")
      ->capture_default_str();
  cmd->add_option("--cv-nesting", a->cv_nesting,
                  "What each fold refits on its training part: weights (the SSD base) or full (bone recovery and SSD "
                  "alternation too; only with --bones)")
      ->capture_default_str();
  cmd->add_option("--cv-rule", a->cv_rule,
                  "Which cross-validated setting is kept: one-se (the most regularised within one paired standard "
                  "error of the smallest held-out mean), min (the smallest), one-se-unpaired")
      ->capture_default_str();
  cmd->add_option("--max-influences", a->max_influences, "Influence bones per vertex");
  cmd->add_option("--as-ridge", a->as_ridge, "Animation Space ridge λ (relative; with --cv none)");
  cmd->add_option("--mwe-s", a->mwe_s, "MWE ridge scale s, relative to the diagonal (λ_h = s·d⁴/σ²(c_h); with --cv none)");
  cmd->add_option("--mwe-components", a->mwe_components, "MWE principal components kept (0 = all with variance)");
  cmd->add_option("--out", a->out, "Output rig (.npz)");
  cmd->callback([a] { run_fit(*a); });
}

}  // namespace bodymodel::cli
