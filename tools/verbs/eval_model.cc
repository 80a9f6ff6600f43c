// bodymodel eval-model model.npz --test DIR [--test-subjects CSV] --out DIR
// bodymodel eval-model --cross-validate subject|pose --registered REG --subjects CSV --out DIR
#include <fmt/format.h>

#include <filesystem>
#include <map>
#include <set>

#include "core/body_size.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/mesh_io.h"
#include "model/database.h"
#include "model/model_quality.h"
#include "model/part_pca.h"
#include "regression/line_plot.h"
#include "tools/pipeline/output_folder.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct EvalArgs {
  std::string model, test, test_subjects, train, out;
  std::string cross_validate, registered, subjects, standard_pose = "standard";
  std::string components, specificity_components;
  int samples = 1000;
  int iterations = ModelFitOptions().max_iterations, coarse_iterations = ModelFitOptions().continuation_iterations;
  int parts = 0;
  bool training_starts = false;
  double prior = 0;
  uint64_t seed = 1;
  double scale = 0;
  double full_variance = 1.0;
  bool no_baseline = false, force = false, first_mesh_faces = false;
};

std::vector<int> parse_components(const std::string& s) {
  std::vector<int> out;
  for (const auto& item : cli::split_commas(s)) {
    const double v = model_cli::parse_number(item, "--components");
    if (v < 1 || v != std::floor(v)) throw InputError(fmt::format("--components: '{}' is not a count ≥ 1", item));
    out.push_back(static_cast<int>(v));
  }
  return out;
}

// Meshes of `dir` (all .ply/.obj/.off, sorted by name) or those a subjects.csv lists.
std::vector<std::pair<std::string, fs::path>> list_meshes(const fs::path& dir, const std::string& csv) {
  if (!fs::is_directory(dir)) throw InputError(fmt::format("'{}' is not a folder of meshes", dir.string()));
  std::vector<std::pair<std::string, fs::path>> out;
  if (!csv.empty()) {
    std::vector<std::string> missing;
    for (const auto& r : read_mesh_table(csv)) {
      fs::path p = find_registered_mesh(dir, r.mesh);
      if (p.empty()) missing.push_back(r.mesh);
      else out.emplace_back(r.mesh, p);
    }
    if (!missing.empty())
      throw InputError(fmt::format("'{}' names {} mesh(es) that '{}' does not have as .ply/.obj/.off (first: {})", csv,
                                   missing.size(), dir.string(), missing[0]));
    return out;
  }
  for (const auto& e : fs::directory_iterator(dir)) {
    std::string ext = e.path().extension().string();
    for (auto& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    if (e.is_regular_file() && (ext == ".ply" || ext == ".obj" || ext == ".off"))
      out.emplace_back(e.path().stem().string(), e.path());
  }
  std::sort(out.begin(), out.end());
  if (out.empty()) throw InputError(fmt::format("'{}' has no .ply, .obj or .off meshes", dir.string()));
  return out;
}

// Reads meshes, checks the model's topology (error naming the file), scales to mm.
std::vector<Eigen::MatrixX3d> read_checked(const BodyModel& model, const std::vector<std::pair<std::string, fs::path>>& list,
                                           double scale, bool from_model, const std::string& what) {
  std::vector<Eigen::MatrixX3d> out;
  for (const auto& [name, path] : list) {
    Mesh m = read_mesh(path);
    m.V *= scale;
    // A model built with --first-mesh-faces takes meshes with its vertices and any triangles.
    const bool any_faces = model.metadata.contains("source") && model.metadata["source"].value("first_mesh_faces", false);
    model.check_topology(m.V, any_faces && m.V.rows() == model.tmpl->vertex_count() ? Eigen::MatrixX3i(model.tmpl->faces()) : m.F,
                         fmt::format("{} '{}'", what, path.string()));
    check_body_size(m.V, fmt::format("{} '{}'", what, path.string()), "--scale", scale, from_model);
    out.push_back(std::move(m.V));
  }
  return out;
}

std::string csv_number(double v) { return std::isfinite(v) ? fmt::format("{:.6g}", v) : ""; }

void write_reports(const StagedFolder& out, const std::vector<QualityRow>& rows,
                   const std::vector<std::pair<std::string, ModelQuality>>& folds, const std::string& title) {
  std::string q = "model,components,generalisation_mean_mm,generalisation_p95_mm,generalisation_max_mm,"
                  "specificity_mean_mm,specificity_std_mm,compactness,unconverged_fits\n";
  for (const auto& r : rows)
    q += fmt::format("{},{},{},{},{},{},{},{},{}\n", csv_field(r.model), r.components,
                     csv_number(r.generalisation_mean_mm),
                     csv_number(r.generalisation_p95_mm), csv_number(r.generalisation_max_mm),
                     csv_number(r.specificity_mean_mm), csv_number(r.specificity_std_mm), csv_number(r.compactness),
                     r.unconverged_fits);
  write_text_file(out / "quality.csv", q);
  // converged: 1/0 for the model's fits (0 = stopped at the iteration cap), empty for vertex PCA.
  std::string g = "fold,model,mesh,components,mean_mm,p95_mm,max_mm,fit_seconds,converged,start_mm,iterations\n";
  int unconverged = 0, fits = 0;
  for (const auto& [fold, f] : folds)
    for (const auto& m : f.per_mesh) {
      g += fmt::format("{},{},{},{},{},{},{},{:.3f},{},{},{}\n", csv_field(fold), csv_field(m.model),
                       csv_field(m.mesh), m.components, csv_number(m.mean_mm), csv_number(m.p95_mm),
                       csv_number(m.max_mm), m.seconds, m.converged < 0 ? std::string() : std::to_string(m.converged),
                       csv_number(m.start_mm), m.converged < 0 ? std::string() : std::to_string(m.iterations));
      fits += m.converged >= 0;
      unconverged += m.converged == 0;
    }
  write_text_file(out / "generalisation.csv", g);
  if (unconverged > 0)
    cli::warn(fmt::format("{} of {} model fits stopped at their iteration cap (converged = 0 in generalisation.csv)",
                          unconverged, fits));
  // Plot: three panels, the rotation-invariant model (blue) and vertex PCA (orange).
  std::vector<LinePanel> panels;
  for (int which = 0; which < 3; ++which) {
    LinePanel p;
    p.title = which == 0   ? "generalisation mean vertex error mm"
              : which == 1 ? "specificity mean distance to nearest training mesh mm"
                           : "compactness fraction of variance";
    std::vector<double> x, y, x2, y2;
    for (const auto& r : rows) {
      const double v = which == 0 ? r.generalisation_mean_mm : which == 1 ? r.specificity_mean_mm : r.compactness;
      if (!std::isfinite(v)) continue;
      (r.model == "rre" ? x : x2).push_back(r.components);
      (r.model == "rre" ? y : y2).push_back(v);
    }
    if (x.empty()) continue;
    p.x = Eigen::Map<Eigen::VectorXd>(x.data(), x.size());
    p.y = Eigen::Map<Eigen::VectorXd>(y.data(), y.size());
    p.x2 = Eigen::Map<Eigen::VectorXd>(x2.data(), x2.size());
    p.y2 = Eigen::Map<Eigen::VectorXd>(y2.data(), y2.size());
    p.mark_minimum = false;
    panels.push_back(p);
  }
  LinePlotOptions po;
  po.x_label = "components   blue rotation invariant   orange vertex pca";
  if (!panels.empty()) write_line_plot_png(out / "model_quality.png", panels, po);
  // Markdown table.
  std::string md = "# " + title + "\n\n"
                   "| model | K | generalisation mean (mm) | p95 (mm) | specificity (mm) | compactness |\n"
                   "|---|---:|---:|---:|---:|---:|\n";
  for (const auto& r : rows)
    md += fmt::format("| {} | {} | {:.2f} | {:.2f} | {} | {:.4f} |\n", r.model == "rre" ? "rotation-invariant" : "vertex PCA",
                      r.components, r.generalisation_mean_mm, r.generalisation_p95_mm,
                      std::isfinite(r.specificity_mean_mm) ? fmt::format("{:.2f}", r.specificity_mean_mm) : "—",
                      r.compactness);
  write_text_file(out / "quality.md", md);
  fmt::print("{}", md);
}

}  // namespace

namespace {

void add_eval_model_options(CLI::App* cmd, EvalArgs& a) {
  cmd->add_option("model", a.model, "Model (.npz from `bodymodel build`)");
  cmd->add_option("--test", a.test, "Folder of test meshes (the model's topology)");
  cmd->add_option("--test-subjects", a.test_subjects, "CSV (mesh,subject,pose) selecting the test meshes of --test");
  cmd->add_option("--train", a.train, "Folder of the model's training meshes (the one `build` read; needed for the specificity and the baseline)");
  auto* cv = cmd->add_option("--cross-validate", a.cross_validate,
                             "subject: leave one subject out; pose: leave one pose name out (instead of a model)")
                 ->check(CLI::IsMember({"subject", "pose"}));
  cmd->add_option("--registered", a.registered, "With --cross-validate: folder of registered meshes");
  cmd->add_option("--subjects", a.subjects, "With --cross-validate: CSV mesh,subject,pose");
  cmd->add_option("--standard-pose", a.standard_pose, "With --cross-validate: standard pose name (as in build)")
      ->capture_default_str();
  cmd->add_option("--full-variance", a.full_variance,
                  "With --cross-validate: variance fraction each fold's model keeps (1: every component)")
      ->capture_default_str();
  cmd->add_option("--components", a.components,
                  "Comma-separated K values (default 1,2,5,10,20,40,80,... and each model's maximum)");
  cmd->add_option("--samples", a.samples, "Random samples for the specificity (0: skip it)")->capture_default_str();
  cmd->add_option("--specificity-components", a.specificity_components,
                  "Comma-separated K values for the specificity (default 5,20 and each model's maximum)");
  cmd->add_option("--seed", a.seed, "Seed of the specificity samples")->capture_default_str();
  cmd->add_option("--scale", a.scale, "Millimetres per mesh unit (0: the model's, from build --scale)")
      ->capture_default_str();
  cmd->add_flag("--no-baseline", a.no_baseline, "Skip the vertex-PCA baseline");
  cmd->add_option("--iterations", a.iterations, "Maximum Levenberg-Marquardt iterations of each model fit (as fit)")
      ->capture_default_str();
  cmd->add_flag("--training-starts", a.training_starts,
                "Each model fit also tries every training mesh's coefficients as its start (as fit)");
  cmd->add_option("--parts", a.parts,
                  "Evaluate a part-wise model instead: the triangles in this many parts (k-means of their rest "
                  "positions), each part its own PCA of the training encodings (0: the model's global PCA, or the "
                  "part-wise model the file holds, from build --parts)")
      ->capture_default_str();
  cmd->add_option("--coarse-iterations", a.coarse_iterations,
                  "At most this many of --iterations fit only the leading 16 components first (as fit)")
      ->capture_default_str();
  cmd->add_option("--prior", a.prior,
                  "Weight (mm²) of a Gaussian prior on the coefficients of each model fit (0: the plain best fit)")
      ->capture_default_str();
  cmd->add_flag("--first-mesh-faces", a.first_mesh_faces,
                "With --cross-validate: meshes share their vertices, not their triangles (as build --first-mesh-faces)");
  cmd->add_option("--out", a.out, "Output folder")->required();
  cmd->add_flag("--force", a.force, "Replace an existing output folder");
  (void)cv;
}

// One fold's training input (every mesh but those of `key`) and its test meshes; a subject
// whose standard pose is left out takes its first listed mesh instead.
struct FoldData {
  ModelBuildInput in;
  std::vector<Eigen::MatrixX3d> test;
  std::vector<std::string> names;
};

FoldData fold_data(const EvalArgs& a, const ModelBuildInput& all, const std::vector<MeshTableRow>& table,
                   const std::string& key) {
  FoldData d;
  ModelBuildInput& in = d.in;
  std::vector<Eigen::MatrixX3d>& test = d.test;
  std::vector<std::string>& names = d.names;
  in.F = all.F;
  std::map<std::string, bool> has_standard;
  std::vector<int> rows;
  for (size_t i = 0; i < table.size(); ++i) {
    const std::string& k = a.cross_validate == "subject" ? table[i].subject : table[i].pose;
    if (k == key) {
      test.push_back(all.meshes[i]);
      names.push_back(table[i].mesh);
    } else {
      rows.push_back(static_cast<int>(i));
    }
  }
  for (int i : rows) {
    in.meshes.push_back(all.meshes[i]);
    in.scan_ids.push_back(table[i].mesh);
    in.subject_ids.push_back(table[i].subject);
    const bool standard = table[i].pose == a.standard_pose && !has_standard[table[i].subject];
    if (standard) has_standard[table[i].subject] = true;
    in.is_standard_pose.push_back(standard);
  }
  for (size_t r = 0; r < rows.size(); ++r)  // subjects whose standard pose is left out: first listed mesh
    if (!has_standard[in.subject_ids[r]]) {
      has_standard[in.subject_ids[r]] = true;
      in.is_standard_pose[r] = 1;
    }
  in.subject_label_values.resize(in.meshes.size(), 0);
  in.pose_label_values.resize(in.meshes.size(), 0);
  return d;
}

// The model's full PCA replaced by a part-wise PCA of its training samples (model/part_pca.h):
// the file's own (`build --parts`), or with --parts P > 0 one built here the same way; returns
// whether it was.
bool use_part_model(BodyModel& model, int parts) {
  if (!model.parts.empty() && parts > 0 && parts != model.parts.part_count())
    throw InputError(fmt::format("--parts {}: the model file holds a part-wise model of {} parts (give --parts {} "
                                 "or none)",
                                 parts, model.parts.part_count(), model.parts.part_count()));
  if (model.parts.empty() && parts <= 0) return false;
  const bool from_file = !model.parts.empty();
  if (!from_file) model.parts = build_part_model(model.full.pca, *model.tmpl, parts);
  const int count = model.parts.part_count();
  model.full.pca = std::move(model.parts.pca);
  model.parts = PartModel{};
  cli::info(fmt::format("part-wise model{}: {} parts, {} components", from_file ? " (the file's)" : "", count,
                        model.full.pca.component_count()));
  return true;
}

// Quality of a model file on --test meshes (and its training meshes for specificity and the
// vertex-PCA baseline); returns the report's title.
std::string evaluate_model_file(const EvalArgs& a, const ModelQualityOptions& qo,
                                std::vector<std::pair<std::string, ModelQuality>>& folds) {
  if (a.model.empty()) throw InputError("eval-model needs a model (or --cross-validate subject|pose)");
  if (a.test.empty()) throw InputError("eval-model needs --test DIR with the meshes the model never saw");
  refuse_existing_output(a.out, a.force);
  BodyModel model = model_cli::load_model_for_cli(a.model, PartModelUse::read);
  const bool parts = use_part_model(model, a.parts);
  // With a model file K is the user's choice for that model: more than it has is an error
  // (cross-validation folds clamp K to each fold's count instead).
  for (int K : qo.components)
    if (K > model.full.component_count())
      throw InputError(fmt::format("--components {}: the full model of '{}' has {} components", K, a.model,
                                   model.full.component_count()));
  double scale = a.scale;
  const nlohmann::json src = model.metadata.value("source", nlohmann::json::object());
  if (scale == 0) scale = src.value("mm_per_unit", 1.0);
  const auto test_list = list_meshes(a.test, a.test_subjects);
  const auto test = read_checked(model, test_list, scale, a.scale == 0, "test mesh");
  std::vector<std::string> names;
  for (const auto& t : test_list) names.push_back(t.first);
  // Training meshes: from --train or where build read them, named by the full model's samples.
  std::vector<Eigen::MatrixX3d> train;
  const std::string train_dir = !a.train.empty() ? a.train : src.value("registered", "");
  const bool needs_train = a.samples > 0 || !a.no_baseline;  // as the error below promises
  if (!train_dir.empty() && needs_train) {
    std::vector<std::pair<std::string, fs::path>> list;
    std::vector<std::string> missing;
    for (const auto& id : model.full.sample_ids) {
      fs::path p = find_registered_mesh(train_dir, id);
      if (p.empty()) missing.push_back(id);
      else list.emplace_back(id, p);
    }
    if (!missing.empty())
      throw InputError(fmt::format("the model's training mesh '{}' is not in '{}' ({} missing): give --train DIR, "
                                   "or --samples 0 --no-baseline to skip what needs them",
                                   missing[0], train_dir, missing.size()));
    train = read_checked(model, list, scale, a.scale == 0, "training mesh");
  } else if (needs_train) {
    throw InputError("the model does not say where its training meshes are: give --train DIR (or --samples 0 "
                     "--no-baseline)");
  }
  std::set<std::string> train_ids(model.full.sample_ids.begin(), model.full.sample_ids.end());
  std::error_code ec;
  const bool same_folder = !train_dir.empty() && fs::equivalent(train_dir, a.test, ec);
  for (const auto& n : names)
    if (same_folder && train_ids.count(n))
      cli::warn(fmt::format("test mesh '{}' is one of the model's training meshes: that is not generalisation", n));
  cli::ProgressBar bar("eval-model");
  folds.emplace_back("all", evaluate_model_quality(model, train, test, names,
                                                   parts ? 0.0 : model.metadata.value("full_total_variance", 0.0), qo,
                                                   bar.callback()));
  bar.finish();
  return fmt::format("Model quality of {} on {} test meshes", a.model, test.size());
}

// Leave-one-subject-out or leave-one-pose-out: a model built per fold; returns the title.
std::string cross_validate_models(const EvalArgs& a, const ModelQualityOptions& qo,
                                  std::vector<std::pair<std::string, ModelQuality>>& folds) {
  if (!a.model.empty()) throw InputError("--cross-validate builds its own models: do not give a model file");
  if (a.registered.empty() || a.subjects.empty())
    throw InputError("--cross-validate needs --registered DIR and --subjects CSV");
  refuse_existing_output(a.out, a.force);
  RegisteredFolderOptions ro;
  ro.mm_per_unit = a.scale > 0 ? a.scale : 1.0;
  ro.standard_pose = a.standard_pose;
  ro.measure_labels = false;
  ro.use_first_mesh_faces = a.first_mesh_faces;
  cli::ProgressBar read_bar("reading");
  const ModelBuildInput all = read_registered_folder(a.registered, a.subjects, ro, nullptr, read_bar.callback());
  read_bar.finish(fmt::format("{} meshes", all.meshes.size()));
  const auto table = read_mesh_table(a.subjects);
  std::vector<std::string> keys;
  for (const auto& r : table) {
    const std::string& k = a.cross_validate == "subject" ? r.subject : r.pose;
    if (std::find(keys.begin(), keys.end(), k) == keys.end()) keys.push_back(k);
  }
  if (keys.size() < 2)
    throw InputError(fmt::format("--cross-validate {}: '{}' has only {} distinct {}", a.cross_validate, a.subjects,
                                 keys.size(), a.cross_validate));
  for (size_t fi = 0; fi < keys.size(); ++fi) {
    const std::string& key = keys[fi];
    FoldData d = fold_data(a, all, table, key);
    ModelBuildInput& in = d.in;
    const std::vector<Eigen::MatrixX3d>& test = d.test;
    const std::vector<std::string>& names = d.names;
    ModelBuildOptions bo;
    bo.full_pca.variance_threshold = a.full_variance;
    bo.shape_pca.variance_threshold = 1.0;
    bo.allow_pose_only = true;
    ModelBuildSummary bs;
    cli::ProgressBar bar(fmt::format("fold {}/{} ({} {})", fi + 1, keys.size(), a.cross_validate, key));
    BodyModel model = build_body_model(in, bo, &bs);
    const bool parts = use_part_model(model, a.parts);
    folds.emplace_back(key, evaluate_model_quality(model, in.meshes, test, names,
                                                   parts ? 0.0 : bs.full_pca.total_variance, qo,
                                                   bar.callback()));
    bar.finish(fmt::format("{} training meshes, {} components, {} test meshes", in.meshes.size(),
                           model.full.component_count(), test.size()));
  }
  return fmt::format("Leave-one-{}-out over {} folds ({})", a.cross_validate, keys.size(), a.subjects);
}

void run_eval_model(EvalArgs& a) {
  ModelQualityOptions qo;
  qo.components = parse_components(a.components);
  qo.specificity_components = parse_components(a.specificity_components);
  if (a.samples < 0) throw InputError("--samples must be ≥ 0");
  qo.specificity_samples = a.samples;
  qo.seed = a.seed;
  qo.vertex_baseline = !a.no_baseline;
  if (a.iterations < 0) throw InputError("--iterations must be ≥ 0");
  if (a.parts < 0) throw InputError("--parts must be ≥ 0");
  qo.fit.max_iterations = a.iterations;
  qo.fit.try_training_starts = a.training_starts;
  if (a.coarse_iterations < 0) throw InputError("--coarse-iterations must be ≥ 0");
  if (!(a.prior >= 0) || !std::isfinite(a.prior)) throw InputError("--prior must be ≥ 0");
  qo.fit.continuation_iterations = a.coarse_iterations;
  qo.fit.prior_weight = a.prior;
  if (a.scale < 0 || !std::isfinite(a.scale)) throw InputError("--scale must be positive (or 0)");
  if (!(a.full_variance > 0 && a.full_variance <= 1)) throw InputError("--full-variance must be in (0, 1]");
  std::vector<std::pair<std::string, ModelQuality>> folds;
  const std::string title =
      a.cross_validate.empty() ? evaluate_model_file(a, qo, folds) : cross_validate_models(a, qo, folds);
  std::vector<ModelQuality> qs;
  for (const auto& f : folds) qs.push_back(f.second);
  const std::vector<QualityRow> rows = pool_model_quality(qs);
  StagedFolder out(a.out, a.force);
  write_reports(out, rows, folds, title);
  out.commit();
  cli::info(fmt::format("wrote {}/quality.csv, quality.md, generalisation.csv, model_quality.png", a.out));
}

}  // namespace

BODYMODEL_VERB(add_model_eval_verb) {
  auto a = std::make_shared<EvalArgs>();
  auto* cmd = app.add_subcommand(
      "eval-model",
      "Model quality as body-model papers measure it (Styner et al. 2003; docs/model.md §3):\n"
      "generalisation (mean and p95 vertex error of the model FITTED to meshes it never saw, by\n"
      "number of components K), specificity (mean distance of random model samples to the nearest\n"
      "training mesh) and compactness (variance fraction of the first K components), for the\n"
      "rotation-invariant model's full (pose + shape) PCA and for a vertex-position PCA of the same\n"
      "training meshes built in the same run. Writes OUT/quality.csv, quality.md, generalisation.csv\n"
      "(per mesh) and model_quality.png.\n"
      "  With a model: --train names the folder `build` read (model files keep no absolute paths).\n"
      "  With --cross-validate subject|pose: one model per left-out subject (or pose name) is built\n"
      "  in memory from --registered/--subjects, with every component (--full-variance 1), and\n"
      "  the folds are pooled.\n"
      "Examples:\n"
      "  bodymodel eval-model faust6.npz --test $BODYMODEL_DATA/faust-registrations --test-subjects s6.csv \\\n"
      "      --train $BODYMODEL_DATA/faust-registrations --out q/\n"
      "  bodymodel eval-model --cross-validate subject --registered $BODYMODEL_DATA/faust-registrations \\\n"
      "      --subjects faust.csv --scale 1000 --standard-pose p0 --out loso/");
  add_eval_model_options(cmd, *a);
  cmd->callback([a] { run_eval_model(*a); });
}

}  // namespace bodymodel
