// bodymodel morph model.npz --in body.ply --set height_cm=185 --keep weight_kg [--mask arms] --out out.obj
#include <fmt/format.h>

#include "core/io/mesh_io.h"
#include "model/body_regions.h"
#include "model/morph.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

struct MorphArgs {
  std::string model, in, out, mask, sex = "unknown";
  std::vector<std::string> set, keep;
  bool clamp = false, closest = false;
  int iterations = 8;
};

}  // namespace

BODYMODEL_VERB(add_model_morph_verb) {
  auto a = std::make_shared<MorphArgs>();
  auto* cmd = app.add_subcommand(
      "morph",
      "Change a body's labels with the shape model (eq. 11: the smallest change meeting all\n"
      "--set values while holding the --keep labels). Measurable labels (height, weight, girths)\n"
      "are met as MEASURED on the output mesh: a few corrected iterations (model/morph.h).");
  cmd->add_option("model", a->model, "Model (.npz from `bodymodel build`)")->required();
  cmd->add_option("--in", a->in, "Body mesh with the model's topology (OBJ/PLY, mm)")->required();
  cmd->add_option("--set", a->set, "LABEL=VALUE, repeatable (e.g. height_cm=185, sex=female)");
  cmd->add_option("--keep", a->keep, "LABEL to hold at its current value, repeatable");
  cmd->add_option("--mask", a->mask,
                  "Restrict the change to a body region: arms, legs, torso, head, left_arm, ...");
  cmd->add_option("--sex", a->sex, "female|male: for the body-fat measurement")
      ->check(CLI::IsMember({"unknown", "female", "male"}));
  cmd->add_flag("--clamp", a->clamp, "Clamp values far outside the data to the data's range");
  cmd->add_option("--iterations", a->iterations, "Maximum measurement-corrected iterations")
      ->capture_default_str();
  cmd->add_flag("--closest", a->closest,
                "When a target cannot be met, write the closest body the model reaches (exit 0) instead of "
                "failing without output");
  cmd->add_option("--out", a->out, "Output mesh (OBJ/PLY)")->required();
  cmd->callback([a] {
    if (a->set.empty()) throw InputError("morph: nothing to do: give at least one --set LABEL=VALUE");
    auto model = std::make_shared<const BodyModel>(model_cli::load_model_for_cli(a->model));
    const SemanticRegression& reg = model->shape.regression;
    std::vector<LabelCondition> cond;
    for (auto& s : a->set) {
      auto [label, text] = model_cli::split_assignment(s, "--set");
      int i = reg.index(label);
      double v = model_cli::check_label_range(reg.labels[i], model_cli::parse_label_value(label, text), a->clamp);
      cond.push_back(LabelCondition::exact(label, v));
    }
    for (auto& k : a->keep) {
      reg.index(k);
      cond.push_back(LabelCondition::keep_current(k));
    }
    Mesh body = read_mesh(a->in);
    model->check_topology(body.V, body.F, "'" + a->in + "'");
    MorphOptions o;
    o.max_iterations = a->iterations;
    o.sex = a->sex == "female" ? Sex::female : a->sex == "male" ? Sex::male : Sex::unknown;
    if (!a->mask.empty())
      o.triangle_mask = triangle_mask_from_vertices(model->tmpl->faces(), body_region_vertex_mask(model->rig, a->mask));
    ShapeMorpher morpher(model);
    MorphSummary sum;
    Eigen::MatrixX3d out = morpher.morph(body.V, cond, o, &sum);
    fmt::print("{}", sum.report());
    // A target the model cannot meet (height_cm=-5 gave an inside-out 27 cm body, 1e9 a body
    // 3 520 km tall) is a failure, not a result: no file, exit 2, unless asked for the closest.
    if (!sum.converged && !a->closest) {
      std::string missed;
      for (const auto& l : sum.labels)
        if (!l.satisfied)
          missed += fmt::format("{}{} = {:.4g} (reached {:.4g})", missed.empty() ? "" : ", ", l.label, l.target,
                                l.achieved);
      throw InputError(fmt::format("morph: the model cannot meet {} from '{}' after {} iterations; nothing written "
                                   "(--closest writes the closest body, --clamp keeps targets inside the data)",
                                   missed, a->in, sum.iterations));
    }
    write_mesh(a->out, out, body.F);
    if (!sum.converged)
      cli::warn("not every label reached its target (see above): wrote the closest body (--closest)");
    cli::info("wrote " + a->out);
  });
}

}  // namespace bodymodel
