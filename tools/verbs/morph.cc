// bodymodel morph model.npz --in body.ply --set height_cm=185 --keep weight_kg [--mask arms] --out out.obj
// bodymodel morph model.npz --set sex=female --set age_years=40 --set height_cm=165 --set weight_kg=80 --out body.obj
#include <fmt/format.h>

#include "core/body_size.h"
#include "core/data_path.h"
#include "core/io/mesh_io.h"
#include "core/plausibility.h"
#include "population/fit_measurements.h"
#include "model/morph_request.h"
#include "model/body_regions.h"
#include "model/morph.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

struct MorphArgs {
  std::string model, in, out, mask, sex = "unknown";
  std::vector<std::string> set, keep;
  bool clamp = false, reference = false, closest = false;
  std::string change;
  int iterations = 8;
};

}  // namespace

namespace {

void add_morph_options(CLI::App* cmd, MorphArgs& a) {
  cmd->add_option("model", a.model, "Model (.npz from `bodymodel build`)")->required();
  cmd->add_option("--in", a.in, "Body mesh with the model's topology (OBJ/PLY, mm); default: the model's mean body");
  cmd->add_option("--change", a.change,
                  "smallest (eq. 11, the paper; default with --in) or likely (eq. 11 in the metric of the PCA\n"
                  "eigenvalues: the model's conditional mean; default without --in)")
      ->check(CLI::IsMember({"smallest", "likely"}));
  cmd->add_flag("--reference", a.reference,
                "Also fit MakeHuman to the output's height, weight, waist and hip and print that body's "
                "roughness (the plausibility reference; one more MakeHuman fit)");
  cmd->add_option("--set", a.set, "LABEL=VALUE, repeatable (e.g. height_cm=185, sex=female)");
  cmd->add_option("--keep", a.keep, "LABEL to hold at its current value, repeatable");
  cmd->add_option("--mask", a.mask,
                  "Restrict the change to a body region: arms, legs, torso, head, left_arm, ...");
  cmd->add_option("--sex", a.sex, "female|male: for the body-fat measurement")
      ->check(CLI::IsMember({"unknown", "female", "male"}));
  cmd->add_flag("--clamp", a.clamp, "Clamp values far outside the data to the data's range");
  cmd->add_option("--iterations", a.iterations, "Maximum measurement-corrected iterations")
      ->capture_default_str();
  cmd->add_flag("--closest", a.closest,
                "When a target cannot be met, write the closest body the model reaches (exit 0) instead of "
                "failing without output");
  cmd->add_option("--out", a.out, "Output mesh (OBJ/PLY)")->required();
}

void run_morph(MorphArgs& a) {
  if (a.set.empty()) throw InputError("morph: nothing to do: give at least one --set LABEL=VALUE");
  auto model = std::make_shared<const BodyModel>(model_cli::load_model_for_cli(a.model));
  const SemanticRegression& reg = model->shape.regression;
  std::vector<LabelCondition> cond;
  for (auto& s : a.set) {
    auto [label, text] = model_cli::split_assignment(s, "--set");
    int i = reg.index(label);
    double v = model_cli::check_label_range(reg.labels[i], model_cli::parse_label_value(label, text), a.clamp);
    cond.push_back(LabelCondition::exact(label, v));
  }
  for (auto& k : a.keep) {
    reg.index(k);
    cond.push_back(LabelCondition::keep_current(k));
  }
  MorphOptions o = morph_request_options(
      cond, a.sex == "female" ? Sex::female : a.sex == "male" ? Sex::male : Sex::unknown, a.change, a.in.empty(),
      a.iterations);
  ShapeMorpher morpher(model);
  Mesh body;
  if (a.in.empty()) {
    if (!a.keep.empty()) throw InputError("--keep needs a body to keep the labels of (--in)");
    if (!a.mask.empty()) throw InputError("--mask needs a body to restrict the change on (--in)");
    body.F = model->tmpl->faces();
  } else {
    body = read_mesh(a.in);
    model->check_topology(body.V, body.F, "'" + a.in + "'");
    check_body_size(body.V, "'" + a.in + "'");
    if (!a.mask.empty())
      o.triangle_mask = triangle_mask_from_vertices(model->tmpl->faces(), body_region_vertex_mask(model->rig, a.mask));
  }
  const MorphedBody morphed = morph_body(morpher, a.in.empty() ? nullptr : &body.V, cond, o);
  const Eigen::MatrixX3d& out = morphed.V;
  const MorphSummary& sum = morphed.summary;
  const int flipped_before = morphed.folds.flipped_before;
  fmt::print("{}", sum.report());
  // A target the model cannot meet (height_cm=-5 gave an inside-out 27 cm body, 1e9 a body
  // 3 520 km tall) is a failure, not a result: no file, exit 2, unless asked for the closest.
  if (!sum.converged && !a.closest) {
    const std::string missed = unmet_labels(sum);
    throw InputError(fmt::format("morph: the model cannot meet {} from {} after {} iterations; nothing written "
                                 "(--closest writes the closest body, --clamp keeps targets inside the data)",
                                 missed, a.in.empty() ? std::string("the mean body") : "'" + a.in + "'",
                                 sum.iterations));
  }
  write_mesh(a.out, out, body.F);
  if (out.rows() == MakeHuman::kBodyVertexCount) {
    const MakeHuman mh = MakeHuman::load();
    const Roughness r = roughness(out, body.F, mh.trunk_and_limbs_region());
    fmt::print("plausibility: roughness p95 {:.1f} deg, max {:.1f} deg (trunk and limbs), {} self-intersecting "
               "triangle pairs, {} flipped triangles ({} before the fold repair)\n",
               r.p95_deg, r.max_deg, self_intersecting_triangle_pairs(out, body.F), flipped_triangle_count(*model, out),
               flipped_before);
    if (a.reference) {
      // The reference's age: the --set one, else the data's mean age (40 without an age label).
      const int age = model->shape.regression.find("age_years");
      double years = age >= 0 ? model->shape.regression.labels[age].mean : 40;
      for (auto& c : cond)
        if (c.label == "age_years" && !c.keep) years = c.lo;
      const PlausibilityReport p = plausibility_against_makehuman(mh, out, body.F, o.sex, years);
      fmt::print("reference:    nearest MakeHuman body p95 {:.1f} deg, max {:.1f} deg, {} self-intersecting pairs "
                 "(ratio p95 {:.2f}{})\n",
                 p.reference.p95_deg, p.reference.max_deg, p.reference_self_intersections, p.p95_ratio(),
                 p.reference_reached ? "" : "; the reference does not measure exactly as the body");
    }
  }
  if (!sum.converged)
    cli::warn("not every label reached its target (see above): wrote the closest body (--closest)");
  cli::info("wrote " + a.out);
}

}  // namespace

BODYMODEL_VERB(add_model_morph_verb) {
  auto a = std::make_shared<MorphArgs>();
  auto* cmd = app.add_subcommand(
      "morph",
      "Change a body's labels with the shape model (eq. 11: the smallest change meeting all\n"
      "--set values while holding the --keep labels). Measurable labels (height, weight, girths,\n"
      "the survey measurements) are met as MEASURED on the output mesh: a few corrected iterations\n"
      "(model/morph.h). Without --in the start is the model's mean body and the change the most\n"
      "likely one (--change likely): 'the typical person' with the --set labels. Prints the output's\n"
      "roughness and self-intersections (core/plausibility.h).");
  add_morph_options(cmd, *a);
  cmd->callback([a] { run_morph(*a); });
}

}  // namespace bodymodel
