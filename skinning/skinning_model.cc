#include "skinning/skinning_model.h"

#include "core/error.h"

namespace bodymodel {

SkinningModel parse_skinning_model(const std::string& name) {
  if (name == "ssd" || name == "lbs") return SkinningModel::ssd;
  if (name == "dqs") return SkinningModel::dqs;
  if (name == "as" || name == "animation_space") return SkinningModel::as;
  if (name == "mwe") return SkinningModel::mwe;
  if (name == "psd") return SkinningModel::psd;
  if (name == "eigenskin") return SkinningModel::eigenskin;
  if (name == "quadratic") return SkinningModel::quadratic;
  throw InputError("unknown skinning method '" + name + "' (expected ssd, dqs, as, mwe, psd, eigenskin or quadratic)");
}

std::string skinning_model_name(SkinningModel m) {
  switch (m) {
    case SkinningModel::ssd: return "ssd";
    case SkinningModel::dqs: return "dqs";
    case SkinningModel::as: return "as";
    case SkinningModel::mwe: return "mwe";
    case SkinningModel::psd: return "psd";
    case SkinningModel::eigenskin: return "eigenskin";
    case SkinningModel::quadratic: return "quadratic";
  }
  return "?";
}

std::vector<SkinningModel> all_skinning_models() {
  return {SkinningModel::ssd, SkinningModel::dqs, SkinningModel::as, SkinningModel::mwe,
          SkinningModel::psd, SkinningModel::eigenskin, SkinningModel::quadratic};
}

int minimum_examples(SkinningModel m) {
  return m == SkinningModel::ssd || m == SkinningModel::dqs ? 1 : 2;
}

bool FittedModel::is_pose_space() const {
  return model == SkinningModel::psd || model == SkinningModel::eigenskin || model == SkinningModel::quadratic;
}

Eigen::MatrixX3d FittedModel::pose(const BoneTransforms& M) const {
  return is_pose_space() ? evaluate_pose_space(pose_space, M) : evaluate_rig(rig, M);
}

namespace {
void check_count(SkinningModel model, const SkinningExamples& ex) {
  if (ex.pose_count() < minimum_examples(model))
    throw InputError(skinning_model_name(model) + " needs at least " + std::to_string(minimum_examples(model)) +
                     " training examples, found " + std::to_string(ex.pose_count()));
}
}  // namespace

FittedModel fit_model(SkinningModel model, const SkinningExamples& ex, const SkinningRig& lbs,
                      const ModelFitOptions& o, std::string* brief, const ProgressCallback& progress) {
  check_count(model, ex);
  FittedModel out;
  out.model = model;
  switch (model) {
    case SkinningModel::ssd:
      out.rig = lbs;
      if (brief) *brief = "ssd: the base rig";
      break;
    case SkinningModel::dqs:
      out.rig = lbs;
      out.rig.method = SkinningMethod::dqs;
      if (brief) *brief = "dqs: the ssd weights, dual-quaternion blending";
      break;
    case SkinningModel::as: {
      AnimationSpaceFitSummary s;
      out.rig = fit_animation_space(ex, &lbs, o.animation_space, &s, progress);
      if (brief) *brief = s.brief();
      break;
    }
    case SkinningModel::mwe: {
      MweFitSummary s;
      out.rig = fit_mwe(ex, &lbs, o.mwe, &s, progress);
      if (brief) *brief = s.brief();
      break;
    }
    case SkinningModel::psd:
    case SkinningModel::eigenskin:
    case SkinningModel::quadratic: {
      PoseSpaceOptions po = o.pose_space;
      po.method = parse_pose_space_method(skinning_model_name(model));
      PoseSpaceFitSummary s;
      out.pose_space = fit_pose_space(ex, lbs, po, &s, progress);
      if (brief) *brief = s.brief();
      break;
    }
  }
  return out;
}

std::vector<FittedModel> fit_mwe_models(const SkinningExamples& ex, const SkinningRig& lbs,
                                        const MweFitOptions& options, const std::vector<double>& scales) {
  check_count(SkinningModel::mwe, ex);
  std::vector<SkinningRig> rigs = fit_mwe_path(ex, &lbs, options, scales);
  std::vector<FittedModel> out(rigs.size());
  for (size_t k = 0; k < rigs.size(); ++k) {
    out[k].model = SkinningModel::mwe;
    out[k].rig = std::move(rigs[k]);
  }
  return out;
}

}  // namespace bodymodel
