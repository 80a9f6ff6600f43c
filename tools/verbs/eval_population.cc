// bodymodel eval-population model.npz --population nhanes.csv --exclude DB/subjects.csv --count 300 --seed 5 --out realism/
// Realism of the model's "typical person": morphed from the mean body to each held-out person's
// sex, age, height and weight, are the waist and hip measured on the mesh the person's?
#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Dense>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>
#include <sstream>

#include "core/data_path.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/plausibility.h"
#include "model/morph.h"
#include "population/people.h"
#include "tools/console.h"
#include "tools/pipeline/output_folder.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

// People the baseline regression (5 coefficients) is fitted on, at least: 4 per coefficient.
constexpr int kMinBaselinePeople = 20;

struct EvalPopulationArgs {
  std::string model, population, exclude, out, change = "likely";
  std::string girths = "waist_iliac_cm,hips_cm";
  int count = 300, jobs = 0;
  uint64_t seed = 5;
  bool force = false;
};

// The `seqn` column of a synth-db subjects.csv (the people a database was built from).
std::set<std::string> excluded_ids(const fs::path& subjects) {
  const std::vector<CsvRecord> rows = read_csv_file(subjects);
  const std::vector<std::string> header = rows.empty() ? std::vector<std::string>() : rows[0].fields;
  const auto it = std::find(header.begin(), header.end(), "seqn");
  if (it == header.end())
    throw InputError("'" + subjects.string() + "' has no seqn column (not a synth-db --population database)");
  const size_t col = static_cast<size_t>(it - header.begin());
  std::set<std::string> ids;
  for (size_t r = 1; r < rows.size(); ++r) {
    const std::vector<std::string>& cells = rows[r].fields;
    if (col < cells.size() && !cells[col].empty()) ids.insert(cells[col]);
  }
  return ids;
}

// Survey-weighted least squares of y on [1, male, age, height, weight] over `rows`.
Eigen::VectorXd fit_baseline(const PeopleTable& t, const std::vector<int>& rows, const std::string& girth) {
  Eigen::MatrixXd X(rows.size(), 5);
  Eigen::VectorXd y(rows.size()), w(rows.size());
  for (size_t k = 0; k < rows.size(); ++k) {
    const Person& p = t.people[rows[k]];
    X.row(k) << 1, p.sex == Sex::male ? 1 : 0, p.age_years, p.measurement("height_cm"), p.measurement("weight_kg");
    y(k) = p.measurement(girth);
    w(k) = p.survey_weight > 0 ? p.survey_weight : 1;
  }
  const Eigen::VectorXd sw = w.cwiseSqrt();
  return (sw.asDiagonal() * X).colPivHouseholderQr().solve(sw.asDiagonal() * y);
}

double baseline_predict(const Eigen::VectorXd& b, const Person& p) {
  return b(0) + b(1) * (p.sex == Sex::male ? 1 : 0) + b(2) * p.age_years + b(3) * p.measurement("height_cm") +
         b(4) * p.measurement("weight_kg");
}

}  // namespace

namespace {

void add_eval_population_options(CLI::App* cmd, EvalPopulationArgs& a) {
  cmd->add_option("model", a.model, "Model (.npz from `bodymodel build` on a synth-db --population database)")->required();
  cmd->add_option("--population", a.population, "The people file (NHANES or own columns)")->required();
  cmd->add_option("--exclude", a.exclude, "subjects.csv of the database the model was built from (its seqn are left out)");
  cmd->add_option("--count", a.count, "People to evaluate")->capture_default_str()->check(CLI::Range(1, 100000));
  cmd->add_option("--seed", a.seed, "Seed of the draw")->capture_default_str();
  cmd->add_option("--girths", a.girths, "Girths compared (recorded names)")->capture_default_str();
  cmd->add_option("--change", a.change, "likely (conditional mean, default) or smallest (eq. 11)")
      ->check(CLI::IsMember({"smallest", "likely"}))
      ->capture_default_str();
  cmd->add_option("--jobs", a.jobs, "People morphed in parallel (0 = all cores)")->capture_default_str();
  cmd->add_option("--out", a.out, "Output folder")->required();
  cmd->add_flag("--force", a.force, "Replace an existing output folder");
}

// Who is evaluated (drawn by survey weight, the --exclude database's people left out) and who
// the baseline regression is fitted on (every other eligible adult).
struct EvaluationPeople {
  PeopleTable table;
  std::vector<std::string> girths;
  std::vector<int> drawn, training;
};

EvaluationPeople choose_people(const EvalPopulationArgs& a) {
  EvaluationPeople P;
  P.table = read_people(a.population);
  const PeopleTable& table = P.table;
  P.girths = cli::split_commas(a.girths);
  const std::vector<std::string>& girths = P.girths;
  std::vector<std::string> needed = {"sex", "age_years", "height_cm", "weight_kg"};
  needed.insert(needed.end(), girths.begin(), girths.end());
  require_columns(table, needed);
  PopulationFilter filter;
  filter.required = {"height_cm", "weight_kg"};
  filter.required.insert(filter.required.end(), girths.begin(), girths.end());
  const EligibleSummary e = eligible_people(table, filter);
  std::set<std::string> skip;
  if (!a.exclude.empty()) skip = excluded_ids(a.exclude);
  std::vector<int> candidates;
  for (int i : e.eligible)
    if (!skip.count(table.people[i].id)) candidates.push_back(i);
  P.drawn = sample_population(table, candidates, a.count, a.seed);
  const std::vector<int>& drawn = P.drawn;
  const std::set<int> drawn_set(drawn.begin(), drawn.end());
  for (int i : e.eligible)
    if (!drawn_set.count(i)) P.training.push_back(i);
  if (drawn.empty())
    throw InputError(fmt::format("'{}': no eligible adult is left to evaluate ({} eligible, {} of them the "
                                 "--exclude database's people)",
                                 a.population, e.eligible.size(), e.eligible.size() - candidates.size()));
  // The baseline has 5 coefficients: fitted on fewer people than this it predicts nothing (on
  // none it predicted 0 and the ratios compared the model with that).
  if (static_cast<int>(P.training.size()) < kMinBaselinePeople)
    throw InputError(fmt::format(
        "'{}': the height/weight baseline regression needs at least {} eligible adults besides the {} drawn for "
        "evaluation, found {} ({} eligible in all): give a larger people file or a smaller --count",
        a.population, kMinBaselinePeople, drawn.size(), P.training.size(), e.eligible.size()));
  cli::info(fmt::format("{}: {} eligible adults, {} left out as the database's people, {} drawn for evaluation, "
                        "the regression fitted on the other {}",
                        a.population, e.eligible.size(), e.eligible.size() - candidates.size(), drawn.size(),
                        P.training.size()));
  return P;
}

void run_eval_population(EvalPopulationArgs& a) {
  const EvaluationPeople people = choose_people(a);
  const PeopleTable& table = people.table;
  const std::vector<std::string>& girths = people.girths;
  const std::vector<int>& drawn = people.drawn;
  const std::vector<int>& training = people.training;
  StagedFolder out(a.out, a.force);
  auto model = std::make_shared<const BodyModel>(model_cli::load_model_for_cli(a.model));
  const SemanticRegression& reg = model->shape.regression;
  for (const char* l : {"sex", "age_years", "height_cm", "weight_kg"}) reg.index(l);
  std::vector<Eigen::VectorXd> baseline;
  for (const auto& g : girths) baseline.push_back(fit_baseline(table, training, g));
  const ShapeMorpher morpher(model);
  struct Row {
    BodyMeasurements m;
    bool converged = false;
    int self_intersections = 0;
    double roughness_p95 = 0;
  };
  std::vector<Row> rows(drawn.size());
  std::vector<char> region;
  if (!model->rig.empty()) region = trunk_and_limbs_region(model->rig.bone_names, model->rig.parents, model->rig.weights);
  cli::ProgressBar bar("eval-population");
  const ProgressCallback progress = bar.callback();
  std::mutex mutex;
  std::atomic<int> done{0};
  tbb::task_arena arena(a.jobs > 0 ? a.jobs : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(0, static_cast<int>(drawn.size()), [&](int k) {
      const Person& p = table.people[drawn[k]];
      std::vector<LabelCondition> cond;
      for (const char* l : {"sex", "age_years", "height_cm", "weight_kg"}) {
        const LabelInfo& info = reg.labels[reg.index(l)];
        const double v = std::string(l) == "sex" ? (p.sex == Sex::male ? 1.0 : 0.0)
                         : std::string(l) == "age_years" ? p.age_years
                                                         : p.measurement(l);
        cond.push_back(LabelCondition::exact(l, std::string(l) == "sex" ? v : std::clamp(v, info.min, info.max)));
      }
      MorphOptions o;
      o.sex = p.sex;
      o.prior_weighted = a.change == "likely";
      // morph_body: the morph and fold repair `morph` runs; measured after the repair.
      const MorphedBody m = morph_body(morpher, nullptr, cond, o);
      const Eigen::MatrixX3d& V = m.V;
      const MorphSummary& s = m.summary;
      Row& r = rows[k];
      r.m = measure_morphed(morpher, V, p.sex, cond);
      r.converged = s.converged;
      r.self_intersections = self_intersecting_triangle_pairs(V, model->tmpl->faces());
      r.roughness_p95 = roughness(V, model->tmpl->faces(), region).p95_deg;
      const int d = ++done;
      std::lock_guard<std::mutex> lock(mutex);
      report_progress(progress, static_cast<double>(d) / drawn.size(), p.id);
    });
  });
  bar.finish();
  std::string csv = "seqn,sex,age_years,height_cm,weight_kg,measured_height_cm,measured_weight_kg,converged";
  for (const auto& g : girths) csv += fmt::format(",{0}_recorded,{0}_model,{0}_regression", g);
  csv += ",roughness_p95_deg,self_intersections\n";
  std::vector<double> se_model(girths.size(), 0), se_reg(girths.size(), 0), bias_model(girths.size(), 0),
      bias_reg(girths.size(), 0);
  int converged = 0;
  for (size_t k = 0; k < drawn.size(); ++k) {
    const Person& p = table.people[drawn[k]];
    const Row& r = rows[k];
    converged += r.converged;
    csv += fmt::format("{},{},{:.0f},{:.1f},{:.1f},{:.2f},{:.2f},{}", csv_field(p.id),
                       p.sex == Sex::male ? "male" : "female",
                       p.age_years, p.measurement("height_cm"), p.measurement("weight_kg"), r.m.height_cm,
                       r.m.weight_kg, r.converged ? 1 : 0);
    for (size_t g = 0; g < girths.size(); ++g) {
      const double rec = p.measurement(girths[g]), mod = measurement_value(r.m, girths[g]),
                   lin = baseline_predict(baseline[g], p);
      csv += fmt::format(",{:.1f},{:.2f},{:.2f}", rec, mod, lin);
      se_model[g] += (mod - rec) * (mod - rec);
      se_reg[g] += (lin - rec) * (lin - rec);
      bias_model[g] += mod - rec;
      bias_reg[g] += lin - rec;
    }
    csv += fmt::format(",{:.2f},{}\n", r.roughness_p95, r.self_intersections);
  }
  write_text_file(out / "realism.csv", csv);
  const double n = static_cast<double>(drawn.size());
  std::string summary = "girth,people,rmse_model_cm,rmse_regression_cm,ratio,bias_model_cm,bias_regression_cm\n";
  fmt::print("{:<16} {:>8} {:>14} {:>18} {:>7} {:>12} {:>16}\n", "girth", "people", "RMSE model", "RMSE regression",
             "ratio", "bias model", "bias regression");
  for (size_t g = 0; g < girths.size(); ++g) {
    const double rm = std::sqrt(se_model[g] / n), rr = std::sqrt(se_reg[g] / n);
    summary += fmt::format("{},{},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f}\n", girths[g], drawn.size(), rm, rr, rm / rr,
                           bias_model[g] / n, bias_reg[g] / n);
    fmt::print("{:<16} {:>8} {:>11.2f} cm {:>15.2f} cm {:>7.3f} {:>+9.2f} cm {:>+13.2f} cm\n", girths[g], drawn.size(), rm,
               rr, rm / rr, bias_model[g] / n, bias_reg[g] / n);
  }
  fmt::print("morphs meeting sex, age, height and weight as measured: {} of {}\n", converged, drawn.size());
  write_text_file(out / "summary.csv", summary);
  out.commit();
  cli::info("wrote " + a.out + "/realism.csv and summary.csv");
}

}  // namespace

BODYMODEL_VERB(add_eval_population_verb) {
  auto a = std::make_shared<EvalPopulationArgs>();
  auto* cmd = app.add_subcommand(
      "eval-population",
      "Realism of the model against real people it never saw: draws --count adults of a people file by\n"
      "survey weight (leaving out the --exclude database's people), morphs the model's mean body to each\n"
      "one's sex, age, height and weight (`morph` without --in), and compares the girths MEASURED on\n"
      "the mesh (waist at the iliac crest, hip) with the person's recorded ones, beside the best\n"
      "height/weight-only predictor: a survey-weighted linear regression of the girth on sex, age,\n"
      "height and weight fitted on every other eligible row of the file. Writes OUT/realism.csv (one\n"
      "row per person) and OUT/summary.csv (RMSE and bias of both, and their ratio).");
  add_eval_population_options(cmd, *a);
  cmd->callback([a] { run_eval_population(*a); });
}

}  // namespace bodymodel
