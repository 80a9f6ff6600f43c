// bodymodel eval-regressors model.npz --folds 10 --labels height_cm,weight_kg,... --out report/
// Hasler et al. 2009 §5.1: cross-validated comparison of linear and non-linear label regressors
// on the model's PCA coefficients (Table 1) and the spread of morph directions (Table 2).
#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <atomic>
#include <mutex>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <random>

#include "core/random_subject.h"
#include "core/ansur_measure.h"
#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/npz.h"
#include "core/makehuman.h"
#include "core/measure.h"
#include "model/body_model.h"
#include "model/model_file.h"
#include "population/ansur.h"
#include "regression/label_noise.h"
#include "regression/line_plot.h"
#include "regression/regression_study.h"
#include "tools/console.h"
#include "tools/synth/synthetic_scans.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

struct EvalRegressorsArgs {
  std::string model;
  int folds = 10;
  std::string labels = "height_cm,weight_kg,body_fat_pct,muscle,waist_cm";
  std::string regressors = "simple_linear,filtered_linear,svr,gaussian_process";
  std::string out = "report";
  std::string set = "shape";
  unsigned seed = 1;
  int jobs = 0;
  bool no_directions = false;
  int synthetic = 0;            // > 0: build the shape model of this many synthetic subjects in-process
  unsigned synthetic_seed = 1;
  std::string save_model;       // with --synthetic: also write the built model here
  std::string label_noise;      // LabelNoiseSpec text (regression/label_noise.h)
  std::string table;            // an ANSUR II file: features are --inputs columns, labels the others
  // --table: the feature columns (empty = male,Age,stature,weightkg); with a model: label columns
  // used as the features instead of the coefficients (empty = the coefficients).
  std::string inputs;
};

// What the study runs on: features, all labels, their names/units, and the subject of each row.
struct StudyInput {
  std::string source;            // for messages
  Eigen::MatrixXd X, Y;
  std::vector<std::string> names, units;
  std::vector<int> groups;
  std::string coef_key = "shape_coefficients";
};

// A list stored as JSON text (the model file, model/model_file.h) or comma-separated text.
std::vector<std::string> read_list(const Npz& z, const std::string& key, const std::string& file) {
  const std::string text = z.text(key);
  if (!text.empty() && text.front() == '[') {
    try {
      return nlohmann::json::parse(text).get<std::vector<std::string>>();
    } catch (const std::exception& e) {
      throw InputError("'" + file + "': key '" + key + "' is not a JSON list of strings: " + e.what());
    }
  }
  return cli::split_commas(text);
}

std::string default_unit(const std::string& label) {
  static const std::map<std::string, std::string> units = {
      {"height_cm", "cm"}, {"weight_kg", "kg"}, {"body_fat_pct", "%"}, {"muscle", "%"},
      {"waist_cm", "cm"},  {"hips_cm", "cm"},   {"chest_cm", "cm"},    {"neck_cm", "cm"},
      {"age_years", "years"}};
  auto it = units.find(label);
  if (it != units.end()) return it->second;
  // ANSUR columns (synth-db on ANSUR files: measured on the body, and ansur2_* as recorded).
  const std::string ansur = label.rfind("ansur2_", 0) == 0 ? label.substr(7) : label;
  const auto& names = AnsurMeasurer::names();
  if (ansur == "Age") return "years";
  if (std::find(names.begin(), names.end(), ansur) != names.end()) return ansur == "weightkg" ? "kg" : "mm";
  const auto u = label.rfind('_');
  return u == std::string::npos ? "" : label.substr(u + 1);
}


// The shape (or full) model's coefficients and labels from a model file (model/model_file.h keys).
StudyInput model_input(const EvalRegressorsArgs& a) {
  const Npz z = Npz::load(a.model);
  const bool full = a.set == "full";
  const std::string p = full ? "full_" : "";
  StudyInput in;
  in.source = a.model;
  in.coef_key = full ? "full_coefficients" : "shape_coefficients";
  for (const std::string& key : {in.coef_key, p + "labels", p + "label_names"})
    if (!z.has(key))
      throw InputError("'" + a.model + "': missing array '" + key + "' (expected a model file with " +
                       in.coef_key + ", " + p + "labels and " + p + "label_names)");
  in.X = z.matrix(in.coef_key);
  in.Y = z.matrix(p + "labels");
  in.names = read_list(z, p + "label_names", a.model);
  in.units.assign(in.names.size(), "");
  if (z.has(p + "label_units")) in.units = read_list(z, p + "label_units", a.model);
  if (in.Y.rows() != in.X.rows() || static_cast<size_t>(in.Y.cols()) != in.names.size() ||
      in.units.size() != in.names.size())
    throw InputError(fmt::format("'{}': {} is {}×{}, {}labels {}×{}, {} label names, {} units (expected "
                                 "one label row per coefficient row and one name and unit per column)",
                                 a.model, in.coef_key, in.X.rows(), in.X.cols(), p, in.Y.rows(), in.Y.cols(),
                                 in.names.size(), in.units.size()));
  // Subjects: one a row for the shape model; grouped scans for the full model.
  const std::string id_key =
      full ? (z.has("full_subject_ids") ? "full_subject_ids" : "full_sample_ids") : "subject_ids";
  if (z.has(id_key)) {
    std::vector<std::string> ids = read_list(z, id_key, a.model);
    if (static_cast<Eigen::Index>(ids.size()) != in.X.rows())
      throw InputError(fmt::format("'{}': {} has {} entries for {} rows", a.model, id_key, ids.size(), in.X.rows()));
    std::map<std::string, int> index;
    for (auto& id : ids) {
      if (full && id_key == "full_sample_ids") {
        const auto cut = id.rfind("_p");
        if (cut != std::string::npos) id = id.substr(0, cut);
      }
      in.groups.push_back(index.emplace(id, static_cast<int>(index.size())).first->second);
    }
  }
  return in;
}

// The shape-only model of `a.synthetic` synthetic subjects built in-process: what
// `synth-db --poses-per-subject 0` + `build DB/truth --shape-variance 1` give (perfect
// registrations: the standard-pose truth meshes), without simulating the scans. Labels are those
// of synth-db's subjects.csv, measured the same way on the standard-pose mesh.
StudyInput synthetic_input(const EvalRegressorsArgs& a) {
  if (a.synthetic < 2) throw InputError("--synthetic: needs at least 2 subjects");
  if (a.set != "shape") throw InputError("--synthetic builds a shape-only model; --set full needs a model file");
  cli::info("loading MakeHuman data");
  const MakeHuman mh = MakeHuman::load();
  std::mt19937_64 rng(a.synthetic_seed);
  const int n = a.synthetic;
  std::vector<MacroSettings> sliders;
  for (int s = 0; s < n; ++s) sliders.push_back(random_makehuman_subject(rng, s % 2 == 1));
  ModelBuildInput b;
  b.meshes.resize(n);
  const std::vector<std::pair<std::string, std::string>> label_info = {
      {"height_cm", "cm"}, {"weight_kg", "kg"}, {"body_fat_pct", "%"}, {"muscle", "%"}, {"waist_cm", "cm"},
      {"hips_cm", "cm"},   {"chest_cm", "cm"},  {"neck_cm", "cm"},     {"age_years", "years"}, {"sex", ""}};
  for (const auto& [name, unit] : label_info) b.subject_labels.push_back({name, unit});
  b.subject_label_values.resize(n, static_cast<Eigen::Index>(label_info.size()));
  std::vector<Eigen::MatrixX3i> faces(n);
  {
    cli::ProgressBar bar("synthetic subjects");
    std::atomic<int> done{0};
    std::mutex m;
    const ProgressCallback cb = bar.callback();
    tbb::task_arena arena(a.jobs > 0 ? a.jobs : tbb::task_arena::automatic);
    arena.execute([&] {
      tbb::parallel_for(0, n, [&](int s) {
        const MakeHuman::Body body = mh.body(sliders[s]);
        const bool male = sliders[s].gender >= 0.5;
        const BodyMeasurements mm = measure_body(body.mesh.V, body.mesh.F, male ? Sex::male : Sex::female);
        b.subject_label_values.row(s) << mm.height_cm, mm.weight_kg, mm.body_fat_pct, sliders[s].muscle * 100,
            mm.waist_cm, mm.hips_cm, mm.chest_cm, mm.neck_cm, sliders[s].age_years(), male ? 1.0 : 0.0;
        b.meshes[s] = body.mesh.V;
        faces[s] = body.mesh.F;
        const int k = ++done;
        std::lock_guard<std::mutex> lock(m);
        report_progress(cb, static_cast<double>(k) / n, "MakeHuman bodies");
      });
    });
    bar.finish(fmt::format("{} subjects", n));
  }
  b.F = faces[0];
  b.pose_label_values.resize(n, 0);
  for (int s = 0; s < n; ++s) {
    char id[32];
    std::snprintf(id, sizeof id, "s%03d", s);
    b.subject_ids.push_back(id);
    b.scan_ids.push_back(std::string(id) + "_p0");
    b.is_standard_pose.push_back(1);
  }
  ModelBuildOptions o;
  o.shape_pca.variance_threshold = 1.0;  // every component: as many as the data has (N − 1)
  o.full_pca.max_components = 1;         // the full model is not used here
  ModelBuildSummary summary;
  cli::ProgressBar bar("build");
  BodyModel model = build_body_model(b, o, &summary, bar.callback());
  bar.finish(fmt::format("shape model: {} subjects, {} components", summary.shape_pca.samples,
                         summary.shape_pca.components));
  if (!a.save_model.empty()) {
    model.metadata["source"] = {{"synthetic_subjects", n}, {"seed", a.synthetic_seed}};
    save_model(a.save_model, model);
    cli::info("wrote " + a.save_model);
  }
  StudyInput in;
  in.source = fmt::format("synthetic shape model ({} subjects, seed {})", n, a.synthetic_seed);
  in.X = model.shape.pca.coefficients;
  in.Y = model.shape.labels;
  for (const auto& l : model.shape.regression.labels) {
    in.names.push_back(l.name);
    in.units.push_back(l.unit);
  }
  if (static_cast<Eigen::Index>(in.names.size()) != in.Y.cols()) {  // labels as given to the build
    in.names.clear(), in.units.clear();
    for (const auto& [name, unit] : label_info) in.names.push_back(name), in.units.push_back(unit);
  }
  return in;
}
// A table of measured people (ANSUR II): the --inputs columns ("male": 1 for men) are the
// features, every numeric column a label; one row a person.
StudyInput table_input(const EvalRegressorsArgs& a) {
  const std::vector<std::string> inputs = cli::split_commas(a.inputs.empty() ? "male,Age,stature,weightkg" : a.inputs);
  if (inputs.empty()) throw InputError("--inputs: no column given");
  std::vector<std::string> required;
  for (const auto& c : inputs)
    if (c != "male") required.push_back(c);
  // The labels too: a missing or renamed label column is then refused as the reader words it.
  for (const auto& c : cli::split_commas(a.labels))
    if (std::find(required.begin(), required.end(), c) == required.end()) required.push_back(c);
  const AnsurTable t = read_ansur(a.table, required);
  StudyInput in;
  in.source = a.table;
  in.X.resize(t.values.rows(), Eigen::Index(inputs.size()));
  for (size_t k = 0; k < inputs.size(); ++k)
    if (inputs[k] == "male")
      for (Eigen::Index r = 0; r < in.X.rows(); ++r) in.X(r, Eigen::Index(k)) = t.male[size_t(r)];
    else
      in.X.col(Eigen::Index(k)) = t.values.col(t.column(inputs[k]));
  in.Y = t.values;
  in.names = t.columns;
  for (const auto& c : t.columns) in.units.push_back(c == "weightkg" ? "kg" : c == "Age" ? "years" : "mm");
  return in;
}

// A model's --inputs labels (e.g. sex,age_years,ansur2_stature,ansur2_weightkg) as the features in
// place of its coefficients: the baseline a body's coefficients are compared with, on the same rows
// and folds. Each feature is divided by its standard deviation over every row (unsupervised, no
// label seen): the kernel regressors' one global scale would otherwise be stature's, in mm, and
// ignore sex; the linear regressors are unchanged by it.
void use_label_features(StudyInput& in, const std::string& inputs) {
  const std::vector<std::string> cols = cli::split_commas(inputs);
  if (cols.empty()) throw InputError("--inputs: no label given");
  Eigen::MatrixXd X(in.Y.rows(), Eigen::Index(cols.size()));
  for (size_t k = 0; k < cols.size(); ++k) {
    const auto it = std::find(in.names.begin(), in.names.end(), cols[k]);
    if (it == in.names.end()) throw InputError("--inputs: '" + cols[k] + "' is not a label of '" + in.source + "'");
    const Eigen::VectorXd c = in.Y.col(it - in.names.begin());
    for (Eigen::Index r = 0; r < c.size(); ++r)
      if (!std::isfinite(c(r)))
        throw InputError(fmt::format("--inputs: label '{}' of '{}' has no value on row {}", cols[k], in.source, r + 1));
    const double sd = std::sqrt((c.array() - c.mean()).square().mean());
    X.col(Eigen::Index(k)) = c / (sd > 0 ? sd : 1.0);
  }
  in.X = X;
  in.source += " (features: " + inputs + ")";
}

}  // namespace

namespace {

void add_eval_regressors_options(CLI::App* cmd, EvalRegressorsArgs& a) {
  cmd->add_option("model", a.model, "Model file (.npz), e.g. from `bodymodel build` (or use --synthetic)");
  cmd->add_option("--synthetic", a.synthetic,
                  "Instead of a model file: build the shape-only model of this many synthetic subjects\n"
                  "in-process (synth-db's subject distribution, standard-pose truth meshes, every PCA\n"
                  "component kept) and evaluate on it");
  cmd->add_option("--table", a.table,
                  "Instead of a model: an ANSUR II file (anthropometry/ansur2/ansur2_male.csv); the features\n"
                  "are the --inputs columns, the labels any other numeric columns (mm; weightkg in kg)");
  cmd->add_option("--inputs", a.inputs,
                  "With --table: the feature columns ('male' = 1 for men; default male,Age,stature,weightkg).\n"
                  "With a model: labels used as the features instead of its coefficients (e.g.\n"
                  "sex,age_years,ansur2_stature,ansur2_weightkg), each divided by its standard deviation");
  cmd->add_option("--synthetic-seed", a.synthetic_seed, "Seed of the synthetic subjects")->capture_default_str();
  cmd->add_option("--save-model", a.save_model, "With --synthetic: also write the built model (.npz)");
  cmd->add_option("--label-noise", a.label_noise,
                  "Simulated measurement noise added to the labels before cross-validation (seeded by\n"
                  "--seed): '0.2' = 0.2 x each label's standard deviation, or 'height_cm=1,weight_kg=0.5'\n"
                  "(sigma in the label's unit). RMSE is then against the noisy labels, as with measured ones");
  cmd->add_option("--folds", a.folds, "Cross-validation folds (subjects grouped)")
      ->capture_default_str()
      ->check(CLI::Range(2, 1000000));
  cmd->add_option("--labels", a.labels, "Comma-separated label names; 'pose:*' = every joint angle")
      ->capture_default_str();
  cmd->add_option("--regressors", a.regressors, "Comma-separated: simple_linear, filtered_linear (the nested fits on the most\ncorrelated components, stacked on their leave-one-subject-out predictions), svr,\ngaussian_process (also filtered_linear_select: the one count with the lowest leave-one-out\nerror; filtered_linear_by_s: ranked by |s|; filtered_linear_10fold: one count by inner\n10-fold CV)")
      ->capture_default_str();
  cmd->add_option("--out", a.out, "Report folder")->capture_default_str();
  cmd->add_option("--set", a.set, "shape (one row a subject) or full (every scan)")
      ->check(CLI::IsMember({"shape", "full"}))
      ->capture_default_str();
  cmd->add_option("--seed", a.seed, "Seed of the fold assignment")->capture_default_str();
  cmd->add_option("--jobs", a.jobs, "Worker threads (0 = all cores)")->capture_default_str();
  cmd->add_flag("--no-directions", a.no_directions, "Skip the morph-direction angles (Table 2)");
}

// The --labels columns of the study's labels (pose:* = every pose label), joint angles in degrees.
struct SelectedLabels {
  Eigen::MatrixXd Y;
  std::vector<std::string> names, units;
};

SelectedLabels select_labels(const StudyInput& in, const std::string& labels) {
  const std::vector<std::string>& names = in.names;
  const std::vector<std::string>& units = in.units;
  const Eigen::MatrixXd& Y = in.Y;
  std::vector<std::string> wanted;
  for (const auto& l : cli::split_commas(labels)) {
    if (l == "pose:*") {
      for (const auto& n : names)
        if (n.rfind("pose:", 0) == 0) wanted.push_back(n);
    } else {
      wanted.push_back(l);
    }
  }
  if (wanted.empty()) throw InputError("--labels: no label selected");
  Eigen::MatrixXd Ysel(Y.rows(), wanted.size());
  std::vector<std::string> sel_units;
  for (size_t k = 0; k < wanted.size(); ++k) {
    const auto it = std::find(names.begin(), names.end(), wanted[k]);
    if (it == names.end()) {
      std::string known;
      for (const auto& n : names) known += (known.empty() ? "" : ", ") + n;
      throw InputError("--labels: '" + wanted[k] + "' is not in '" + in.source + "' (it has " + known + ")");
    }
    const size_t c = static_cast<size_t>(it - names.begin());
    Ysel.col(k) = Y.col(c);
    std::string unit = units[c].empty() ? default_unit(wanted[k]) : units[c];
    if (wanted[k].rfind("pose:", 0) == 0 && (unit == "rad" || unit == "radians" || unit.empty())) {
      Ysel.col(k) *= 180.0 / M_PI;  // joint angles reported in degrees
      unit = "deg";
    }
    sel_units.push_back(unit);
  }
  return {Ysel, wanted, sel_units};
}

// regressors.csv, directions.csv and the filtered-linear curves (CSV and plot) in `dir`.
void write_regression_outputs(const std::string& dir, const RegressionStudy& study, const RegressionStudyOptions& o,
                              const std::vector<std::string>& wanted, const std::vector<std::string>& sel_units) {
  const std::filesystem::path out(dir);
  ensure_directory(out);
  std::string csv = "regressor,label,unit,rmse,mae,folds,samples,skipped_missing\n";
  for (const auto& r : o.regressors)
    for (size_t k = 0; k < wanted.size(); ++k) {
      const auto& s = study.result(r, wanted[k]);
      csv += fmt::format("{},{},{},{:.6g},{:.6g},{},{},{}\n", r, csv_field(wanted[k]), csv_field(sel_units[k]),
                         s.rmse, s.mae, s.folds, s.samples, s.skipped_missing);
    }
  write_text_file(out / "regressors.csv", csv);
  if (o.directions) {
    std::string d = "regressor,label,mean_deg,std_deg,max_deg,subjects\n";
    for (const auto& r : study.directions)
      d += fmt::format("{},{},{:.6g},{:.6g},{:.6g},{}\n", r.regressor, csv_field(r.label), r.spread.mean_deg,
                       r.spread.std_deg, r.spread.max_deg, r.spread.subjects);
    write_text_file(out / "directions.csv", d);
    fmt::print("\nMorph-direction angle to the mean direction, degrees (mean ± std over subjects)\n");
    std::string t = fmt::format("{:<22}", "");
    for (const auto& l : wanted) t += fmt::format(" {:>16}", l);
    t += "\n";
    for (const auto& r : o.regressors) {
      t += fmt::format("{:<22}", r);
      for (const auto& dr : study.directions)
        if (dr.regressor == r) t += fmt::format(" {:>16}", fmt::format("{:.2f} ± {:.2f}", dr.spread.mean_deg, dr.spread.std_deg));
      t += "\n";
    }
    fmt::print("{}", t);
  }
  std::vector<LinePanel> panels;
  std::string curve_csv = "label,unit,kept_components,rmse\n";
  for (size_t k = 0; k < wanted.size(); ++k) {
    const Eigen::VectorXd& c = study.filtered_curves[k];
    LinePanel pnl;
    pnl.title = wanted[k] + " rmse (" + sel_units[k] + ") filtered linear";
    pnl.x = Eigen::VectorXd::LinSpaced(c.size(), 1, static_cast<double>(c.size()));
    pnl.y = c;
    panels.push_back(pnl);
    for (Eigen::Index m = 0; m < c.size(); ++m)
      curve_csv += fmt::format("{},{},{},{:.6g}\n", csv_field(wanted[k]), csv_field(sel_units[k]), m + 1, c(m));
  }
  write_line_plot_png(out / "filtered_components.png", panels);
  write_text_file(out / "filtered_components.csv", curve_csv);
}

void run_eval_regressors(EvalRegressorsArgs& a) {
  if ((a.synthetic > 0) + !a.model.empty() + !a.table.empty() > 1)
    throw InputError("give one of a model file, --synthetic N or --table FILE");
  if (a.synthetic <= 0 && a.model.empty() && a.table.empty())
    throw InputError("no model file given (expected model.npz, --synthetic N to build one in-process, or --table FILE)");
  const LabelNoiseSpec noise = parse_label_noise(a.label_noise);
  if (!a.inputs.empty() && a.synthetic > 0) throw InputError("--inputs: with a model file or --table, not --synthetic");
  StudyInput in = a.synthetic > 0 ? synthetic_input(a) : !a.table.empty() ? table_input(a) : model_input(a);
  const bool label_features = !a.inputs.empty() && a.table.empty();
  if (label_features) use_label_features(in, a.inputs);
  const Eigen::MatrixXd& X = in.X;
  const std::vector<int>& groups = in.groups;
  SelectedLabels chosen = select_labels(in, a.labels);
  Eigen::MatrixXd& Ysel = chosen.Y;
  const std::vector<std::string>& wanted = chosen.names;
  const std::vector<std::string>& sel_units = chosen.units;
  if (!noise.empty()) {
    const Eigen::VectorXd sigma = label_noise_sigma(noise, Ysel, wanted);
    Ysel = add_label_noise(Ysel, sigma, groups, a.seed);
    std::string list;
    for (size_t k = 0; k < wanted.size(); ++k)
      list += fmt::format("{}{} {:.3g} {}", k ? ", " : "", wanted[k], sigma(k), sel_units[k]);
    cli::info("simulated label noise (sigma): " + list);
  }

  RegressionStudyOptions o;
  o.regressors = cli::split_commas(a.regressors);
  for (const auto& r : o.regressors) make_regressor(r);  // validates the names
  o.cross_validation.folds = a.folds;
  o.cross_validation.seed = a.seed;
  o.jobs = a.jobs;
  o.directions = !a.no_directions && a.table.empty() && !label_features;  // of a model's coefficients only
  cli::info(fmt::format("{}: {} rows ({} subjects), {} components, {} labels, {} regressors, {}-fold",
                        in.source, X.rows(), groups.empty() ? X.rows() : static_cast<Eigen::Index>(*std::max_element(groups.begin(), groups.end()) + 1),
                        X.cols(), wanted.size(), o.regressors.size(), a.folds));
  cli::ProgressBar bar("eval-regressors");
  const RegressionStudy study = run_regression_study(X, Ysel, wanted, groups, o, bar.callback());
  bar.finish();

  // Table 1 style, with units.
  std::string table = fmt::format("{:<22}", "RMSE");
  for (size_t k = 0; k < wanted.size(); ++k) table += fmt::format(" {:>16}", wanted[k] + " (" + sel_units[k] + ")");
  table += "\n";
  for (const auto& r : o.regressors) {
    table += fmt::format("{:<22}", r);
    for (const auto& l : wanted) table += fmt::format(" {:>16.3f}", study.result(r, l).rmse);
    table += "\n";
  }
  fmt::print("{}", table);
  for (size_t k = 0; k < wanted.size(); ++k) {
    const auto& s = study.result(o.regressors[0], wanted[k]);
    if (s.skipped_missing > 0)
      cli::warn(fmt::format("label '{}': {} rows without a value were skipped ({} used)", wanted[k],
                            s.skipped_missing, s.samples));
  }

  write_regression_outputs(a.out, study, o, wanted, sel_units);
  cli::info(fmt::format("wrote {}/regressors.csv, {}filtered_components.png/.csv", a.out, o.directions ? "directions.csv, " : ""));
}

}  // namespace

BODYMODEL_VERB(add_eval_regressors_verb) {
  auto a = std::make_shared<EvalRegressorsArgs>();
  auto* cmd = app.add_subcommand(
      "eval-regressors",
      "Cross-validate label regressors on a model's PCA coefficients (Hasler et al. 2009 Table 1)\n"
      "and measure how much their morph directions vary across subjects (Table 2).\n"
      "Reads from the .npz: <set>_coefficients (shape: shape_coefficients), labels, label_names,\n"
      "optional label_units and subject_ids (JSON lists or comma-separated text). With --set full\n"
      "the full model's arrays are used, scans are grouped by subject (full_subject_ids, or the scan\n"
      "id up to its last '_p'), and joint-angle labels 'pose:<bone>:r?' are reported in degrees.\n"
      "Writes <out>/regressors.csv, <out>/directions.csv, <out>/filtered_components.png.");
  add_eval_regressors_options(cmd, *a);
  cmd->callback([a] { run_eval_regressors(*a); });
}

}  // namespace bodymodel
