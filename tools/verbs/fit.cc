// bodymodel fit model.npz --in mesh.ply --out fitted.ply [--components K] [--pose]
#include <fmt/format.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/body_size.h"
#include "core/io/atomic_write.h"
#include "core/io/json_text.h"
#include "core/io/mesh_io.h"
#include "core/measure.h"
#include "model/fit.h"
#include "model/fit_labels.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

struct FitArgs {
  std::string model, in, out, json;
  int components = -1;
  bool pose = false;
  double scale = 0;  // 0 = the model's
  int iterations = 20;
  int coarse_iterations = 4;
  double prior = 0;
  bool training_starts = false;
  bool global = false;
  std::string start = "projection";
  std::string sex = "unknown";
};

}  // namespace

namespace {

void add_fit_options(CLI::App* cmd, FitArgs& a) {
  cmd->add_option("model", a.model, "Model (.npz from `bodymodel build`)")->required();
  cmd->add_option("--in", a.in, "Mesh with the model's topology (OBJ, PLY or OFF)")->required();
  cmd->add_option("--out", a.out, "Fitted body (OBJ or PLY, mm)")->required();
  cmd->add_option("--json", a.json, "Coefficients and labels (default: --out with .json)");
  cmd->add_option("--components", a.components, "Leading components to fit (-1: all)")->capture_default_str();
  cmd->add_flag("--pose", a.pose,
                "Fit the full model (pose and shape) instead of the shape-only model (standard-pose bodies)");
  cmd->add_option("--scale", a.scale,
                  "Millimetres per unit of --in (0: the unit the model was built from, e.g. 1000 for FAUST)")
      ->capture_default_str();
  cmd->add_option("--iterations", a.iterations, "Maximum Levenberg-Marquardt iterations")->capture_default_str();
  cmd->add_option("--coarse-iterations", a.coarse_iterations,
                  "At most this many of --iterations fit only the leading 16 components first (0: none)")
      ->capture_default_str();
  cmd->add_option("--prior", a.prior,
                  "Weight (mm²) of a Gaussian prior on the coefficients (0: the plain best fit)")
      ->capture_default_str();
  cmd->add_option("--start", a.start,
                  "projection: of the mesh's encoding onto the components; mean: the model's mean body (c = 0)")
      ->check(CLI::IsMember({"projection", "mean"}))
      ->capture_default_str();
  cmd->add_flag("--training-starts", a.training_starts,
                "Also try each training mesh's coefficients as the start (one decode each) and start from the "
                "closest: for poses far from the projection (docs/model.md §1)");
  cmd->add_flag("--global", a.global,
                "With a part-wise model (`build --parts`): fit the full model's global PCA instead of the parts'");
  cmd->add_option("--sex", a.sex, "female|male: for the body-fat measurement")
      ->check(CLI::IsMember({"unknown", "female", "male"}));
}

// The PCA fitted: a part-wise model's (`build --parts`, model/part_pca.h) when the file has one
// and the full model is fitted, unless --global; else the sub-model's.
const Pca& fitted_pca(const BodyModel& model, const SubModel& sub, bool full, const FitArgs& a) {
  if (full && !model.parts.empty() && !a.global) {
    cli::info(fmt::format("part-wise model: {} parts, {} components (--global: the full model's {})",
                          model.parts.part_count(), model.parts.pca.component_count(), model.full.component_count()));
    return model.parts.pca;
  }
  return sub.pca;
}

// The sub-model's coefficients of the fitted body, for its label regression: a part-wise fit's
// encoding projected onto the global basis (both share the full model's mean).
Eigen::VectorXd label_coefficients(const SubModel& sub, const Pca& pca, const Eigen::VectorXd& c) {
  if (&pca == &sub.pca) return c;
  return sub.pca.basis.transpose() * (pca.basis.leftCols(c.size()) * c);
}

void run_fit(FitArgs& a) {
  namespace fs = std::filesystem;
  if (a.components == 0 || a.components < -1)
    throw InputError(fmt::format("--components must be ≥ 1 or -1, got {}", a.components));
  if (a.scale < 0 || !std::isfinite(a.scale)) throw InputError("--scale must be positive (or 0: the model's)");
  if (a.iterations < 0) throw InputError("--iterations must be ≥ 0");
  if (a.coarse_iterations < 0) throw InputError("--coarse-iterations must be ≥ 0");
  auto model = std::make_shared<const BodyModel>(model_cli::load_model_for_cli(a.model, PartModelUse::read));
  const bool full = a.pose || model->metadata.value("shape_model", "") == "full";
  const SubModel& sub = full ? model->full : model->shape;
  const Pca& pca = fitted_pca(*model, sub, full, a);
  if (a.components > pca.component_count())
    throw InputError(fmt::format("--components {}: the {} model of '{}' has {} components", a.components,
                                 &pca == &sub.pca ? (full ? "full" : "shape") : "part-wise", a.model,
                                 pca.component_count()));
  double scale = a.scale;
  if (scale == 0) {
    scale = 1;
    if (model->metadata.contains("source") && model->metadata["source"].contains("mm_per_unit"))
      scale = model->metadata["source"]["mm_per_unit"].get<double>();
  }
  Mesh mesh = read_mesh(a.in);
  // A model built with --first-mesh-faces takes meshes with its vertices and any triangles.
  if (model->metadata.contains("source") && model->metadata["source"].value("first_mesh_faces", false) &&
      mesh.V.rows() == model->tmpl->vertex_count())
    mesh.F = model->tmpl->faces();
  model->check_topology(mesh.V * scale, mesh.F, "'" + a.in + "'");
  const Eigen::MatrixX3d Y = mesh.V * scale;
  check_body_size(Y, "'" + a.in + "'", "--scale", scale, a.scale == 0);
  ModelFitter fitter(model->tmpl, model->mean, pca);
  ModelFitOptions o;
  o.components = a.components;
  o.max_iterations = a.iterations;
  o.continuation_iterations = a.coarse_iterations;
  o.prior_weight = a.prior;
  o.try_training_starts = a.training_starts;
  o.start_from_projection = a.start == "projection";
  cli::ProgressBar bar("fit");
  ModelFit fit = fitter.fit(Y, o, bar.callback());
  bar.finish(fit.summary.report());
  write_mesh(a.out, fit.V, mesh.F);

  // Labels: predicted (regression on all components, the unfitted ones 0) and measured.
  const Sex sex = a.sex == "female" ? Sex::female : a.sex == "male" ? Sex::male : Sex::unknown;
  nlohmann::json labels = nlohmann::json::object();
  for (const FitLabel& l : fit_labels(*model, sub, label_coefficients(sub, pca, fit.coefficients), Y, fit.V, mesh.F, sex)) {
    nlohmann::json j = {{"unit", l.unit}};
    if (l.predicted) j["predicted"] = *l.predicted;
    if (l.measured_input) j["measured_input"] = *l.measured_input;
    if (l.measured_fitted) j["measured_fitted"] = *l.measured_fitted;
    labels[l.name] = j;
  }
  nlohmann::json out = {
      {"model", a.model},
      {"input", a.in},
      {"sub_model", &pca != &sub.pca ? "parts" : full ? "full" : "shape"},
      {"components", fit.summary.components},
      {"coefficients", std::vector<double>(fit.coefficients.data(), fit.coefficients.data() + fit.coefficients.size())},
      {"input_mm_per_unit", scale},
      {"vertex_error_mm",
       {{"mean", fit.summary.mean_mm}, {"rms", fit.summary.rms_mm}, {"p95", fit.summary.p95_mm}, {"max", fit.summary.max_mm}}},
      {"start_mean_vertex_error_mm", fit.summary.start_mean_mm},
      {"start_training_mesh", fit.summary.start_sample >= 0 && fit.summary.start_sample < int(sub.sample_ids.size())
                                  ? nlohmann::json(sub.sample_ids[fit.summary.start_sample])
                                  : nlohmann::json(nullptr)},
      {"iterations", fit.summary.iterations},
      {"jacobians", fit.summary.jacobians},
      {"decodes", fit.summary.evaluations},
      {"converged", fit.summary.converged},
      {"stop_reason", fit.summary.stop_reason},
      {"history_mean_vertex_error_mm", fit.summary.history_mean_mm},
      {"seconds", fit.summary.seconds},
      {"labels", labels},
      {"note", "measured_* values assume a closed mesh in a standing pose (core/measure.h); predicted values "
               "come from the model's regression (docs/method.md §4.2)"}};
  fs::path json_path = a.json.empty() ? fs::path(a.out).replace_extension(".json") : fs::path(a.json);
  write_text_file(json_path, json_text(out, 2) + "\n");
  fmt::print("{}\n", fit.summary.report());
  // A fit at its iteration cap is not the model's closest body: say so where it cannot be missed.
  if (!fit.summary.converged)
    cli::warn(fmt::format("the fit did not converge: {}; the body written is the last iterate (try --iterations {})",
                          fit.summary.stop_reason, std::max(2 * a.iterations, 40)));
  for (auto& [name, j] : labels.items()) {
    std::string line = fmt::format("  {:<14}", name);
    if (j.contains("predicted")) line += fmt::format(" predicted {:>9.3f}", j["predicted"].get<double>());
    if (j.contains("measured_input")) line += fmt::format("  measured input {:>9.3f}", j["measured_input"].get<double>());
    if (j.contains("measured_fitted")) line += fmt::format("  fitted {:>9.3f}", j["measured_fitted"].get<double>());
    fmt::print("{} {}\n", line, j["unit"].get<std::string>());
  }
  cli::info(fmt::format("wrote {} and {}", a.out, json_path.string()));
}

}  // namespace

BODYMODEL_VERB(add_model_fit_verb) {
  auto a = std::make_shared<FitArgs>();
  auto* cmd = app.add_subcommand(
      "fit",
      "Fit the model to a mesh of its topology (a registered scan): the coefficients, and a rigid\n"
      "placement, that minimise the VERTEX error of the decoded body against the mesh, by\n"
      "Levenberg-Marquardt through the decoder with its exact Jacobian, starting from the\n"
      "projection of the mesh's encoding (docs/model.md). Writes the fitted body (mm, placed on the\n"
      "input) and a JSON with the coefficients, the fit error and every label: predicted by the\n"
      "model's regression from the coefficients and, where a mesh can tell, measured on the input\n"
      "and on the fitted body (measurements assume a standing pose). To morph your own scan: fit,\n"
      "then `bodymodel morph model.npz --in fitted.ply ...`.\n"
      "Example: bodymodel fit faust.npz --in tr_reg_000.off --out fitted.ply --pose");
  add_fit_options(cmd, *a);
  cmd->callback([a] { run_fit(*a); });
}

}  // namespace bodymodel
