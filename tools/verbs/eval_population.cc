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
#include <numeric>
#include <random>
#include <set>
#include <sstream>

#include "core/data_path.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/plausibility.h"
#include "model/morph.h"
#include "population/ansur.h"
#include "population/ansur_fit.h"
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
  cmd->add_option("--girths", a.girths, "Girths compared (recorded names; with ANSUR files, ANSUR columns)")
      ->capture_default_str();
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

// ---- ANSUR II soldiers (--population lists ANSUR files) ----------------------------------------

// The soldiers of one or two ANSUR files: who is evaluated (drawn uniformly, alternating files,
// the --exclude database's subjectid left out) and who the regression is fitted on (the rest).
struct AnsurPeople {
  std::vector<AnsurTable> tables;
  std::vector<std::pair<int, int>> drawn, training;  // (table, row)
};

AnsurPeople choose_soldiers(const EvalPopulationArgs& a, const std::vector<std::string>& columns) {
  AnsurPeople P;
  std::vector<std::string> needed = columns;
  for (const char* c : {"Age", "stature", "weightkg"}) needed.push_back(c);
  for (const auto& f : cli::split_commas(a.population)) P.tables.push_back(read_ansur(f, needed));
  std::set<std::string> skip;
  if (!a.exclude.empty()) {
    const std::vector<CsvRecord> rows = read_csv_file(a.exclude);
    const auto& h = rows.at(0).fields;
    const auto it = std::find(h.begin(), h.end(), "subjectid");
    if (it == h.end()) throw InputError("'" + a.exclude + "' has no subjectid column (not a synth-db ANSUR database)");
    for (size_t r = 1; r < rows.size(); ++r)
      if (static_cast<size_t>(it - h.begin()) < rows[r].fields.size()) skip.insert(rows[r].fields[it - h.begin()]);
  }
  std::mt19937_64 rng(a.seed);
  std::vector<std::vector<int>> order(P.tables.size());
  for (size_t t = 0; t < P.tables.size(); ++t) {
    for (int r = 0; r < static_cast<int>(P.tables[t].ids.size()); ++r)
      if (!skip.count(P.tables[t].ids[r])) order[t].push_back(r);
    std::shuffle(order[t].begin(), order[t].end(), rng);
  }
  std::set<std::pair<int, int>> drawn;
  for (int k = 0; k < a.count; ++k) {
    const int t = k % static_cast<int>(P.tables.size());
    const size_t i = k / P.tables.size();
    if (i < order[t].size()) drawn.insert({t, order[t][i]});
  }
  P.drawn.assign(drawn.begin(), drawn.end());
  for (size_t t = 0; t < P.tables.size(); ++t)
    for (int r = 0; r < static_cast<int>(P.tables[t].ids.size()); ++r)
      if (!drawn.count({static_cast<int>(t), r})) P.training.push_back({static_cast<int>(t), r});
  if (P.drawn.empty() || static_cast<int>(P.training.size()) < kMinBaselinePeople)
    throw InputError(fmt::format("'{}': {} soldiers drawn, {} left for the regression: give more soldiers or a "
                                 "smaller --count", a.population, P.drawn.size(), P.training.size()));
  return P;
}

// Least squares of a column on [1, male, Age, stature, weightkg] over the training soldiers.
Eigen::VectorXd fit_ansur_baseline(const AnsurPeople& P, const std::vector<std::pair<int, int>>& rows,
                                   const std::string& column) {
  Eigen::MatrixXd X(rows.size(), 5);
  Eigen::VectorXd y(rows.size());
  for (size_t k = 0; k < rows.size(); ++k) {
    const AnsurTable& t = P.tables[rows[k].first];
    const int r = rows[k].second;
    X.row(k) << 1, t.male[r], t.values(r, t.column("Age")), t.values(r, t.column("stature")),
        t.values(r, t.column("weightkg"));
    y(k) = t.values(r, t.column(column));
  }
  return X.colPivHouseholderQr().solve(y);
}

// realism.csv (one row per soldier) and summary.csv (per column: RMSE and bias of the morphed
// body and of the regression, their ratio), and the table on stdout.
void write_ansur_realism(const EvalPopulationArgs& a, const AnsurPeople& P, const std::vector<std::string>& columns,
                         const MeasurementSet& set, const std::vector<Eigen::VectorXd>& measured, StagedFolder& out) {
  std::vector<Eigen::VectorXd> baseline;
  for (const auto& c : columns) baseline.push_back(fit_ansur_baseline(P, P.training, c));
  std::string csv = "subjectid,sex,Age,stature,weightkg";
  for (const auto& c : columns) csv += fmt::format(",{0}_survey,{0}_model,{0}_regression", c);
  csv += "\n";
  const size_t C = columns.size();
  std::vector<double> se_m(C, 0), se_r(C, 0), bias_m(C, 0), bias_r(C, 0);
  for (size_t k = 0; k < P.drawn.size(); ++k) {
    const AnsurTable& t = P.tables[P.drawn[k].first];
    const int r = P.drawn[k].second;
    const Eigen::Matrix<double, 5, 1> x(1, t.male[r], t.values(r, t.column("Age")), t.values(r, t.column("stature")),
                                        t.values(r, t.column("weightkg")));
    csv += fmt::format("{},{},{:.0f},{:.0f},{:.1f}", csv_field(t.ids[r]), t.male[r] ? "male" : "female", x(2), x(3), x(4));
    for (size_t c = 0; c < C; ++c) {
      const double truth = t.values(r, t.column(columns[c])), mod = measured[k](set.index(columns[c])),
                   lin = baseline[c].dot(x);
      csv += fmt::format(",{:.1f},{:.2f},{:.2f}", truth, mod, lin);
      se_m[c] += (mod - truth) * (mod - truth), se_r[c] += (lin - truth) * (lin - truth);
      bias_m[c] += mod - truth, bias_r[c] += lin - truth;
    }
    csv += "\n";
  }
  write_text_file(out / "realism.csv", csv);
  const double n = static_cast<double>(P.drawn.size());
  std::string summary = "column,people,rmse_model,rmse_regression,ratio,bias_model,bias_regression\n";
  fmt::print("{:<28} {:>7} {:>11} {:>16} {:>7} {:>11} {:>15}\n", "column (mm, kg)", "people", "RMSE model",
             "RMSE regression", "ratio", "bias model", "bias regression");
  for (size_t c = 0; c < C; ++c) {
    // stature and weight are the morph's inputs: the regression reproduces them, no ratio.
    const double rm = std::sqrt(se_m[c] / n), rr = std::sqrt(se_r[c] / n);
    const bool input = columns[c] == "stature" || columns[c] == "weightkg";
    const std::string ratio = input ? std::string("input") : fmt::format("{:.3f}", rm / rr);
    summary += fmt::format("{},{},{:.3f},{:.3f},{},{:.3f},{:.3f}\n", columns[c], P.drawn.size(), rm, rr,
                           input ? "" : ratio, bias_m[c] / n, bias_r[c] / n);
    fmt::print("{:<28} {:>7} {:>11.2f} {:>16.2f} {:>7} {:>+11.2f} {:>+15.2f}\n", columns[c], P.drawn.size(), rm, rr,
               ratio, bias_m[c] / n, bias_r[c] / n);
  }
  write_text_file(out / "summary.csv", summary);
  cli::info(fmt::format("wrote {}/realism.csv and summary.csv ({} soldiers; regression fitted on {})", a.out,
                        P.drawn.size(), P.training.size()));
}

// eval-population on ANSUR II soldiers: the model's mean body morphed to each drawn soldier's
// sex, age, stature and weight, measured as `measure --standard ansur2` reads it, against the
// soldier's own columns and the regression from those four.
void run_eval_population_ansur(EvalPopulationArgs& a) {
  const std::vector<std::string> columns =
      a.girths == EvalPopulationArgs{}.girths ? default_ansur_columns() : cli::split_commas(a.girths);
  const AnsurPeople P = choose_soldiers(a, columns);
  StagedFolder out(a.out, a.force);
  auto model = std::make_shared<const BodyModel>(model_cli::load_model_for_cli(a.model));
  const SemanticRegression& reg = model->shape.regression;
  const MakeHuman mh = MakeHuman::load();
  const MeasurementSet set = ansur_measurement_set(mh);
  const ShapeMorpher morpher(model);
  std::vector<Eigen::VectorXd> measured(P.drawn.size());
  cli::ProgressBar bar("eval-population");
  const ProgressCallback progress = bar.callback();
  std::mutex mutex;
  std::atomic<int> done{0};
  tbb::task_arena arena(a.jobs > 0 ? a.jobs : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(0, static_cast<int>(P.drawn.size()), [&](int k) {
      const AnsurTable& t = P.tables[P.drawn[k].first];
      const int r = P.drawn[k].second;
      const double v[4] = {double(t.male[r]), t.values(r, t.column("Age")), t.values(r, t.column("stature")) / 10,
                           t.values(r, t.column("weightkg"))};
      std::vector<LabelCondition> cond;
      const char* names[4] = {"sex", "age_years", "height_cm", "weight_kg"};
      for (int l = 0; l < 4; ++l) {
        const LabelInfo& info = reg.labels[reg.index(names[l])];
        cond.push_back(LabelCondition::exact(names[l], l == 0 ? v[l] : std::clamp(v[l], info.min, info.max)));
      }
      MorphOptions o;
      o.sex = t.male[r] ? Sex::male : Sex::female;
      o.prior_weighted = a.change == "likely";
      measured[k] = set.measure(morph_body(morpher, nullptr, cond, o).V);
      const int d = ++done;
      std::lock_guard<std::mutex> lock(mutex);
      report_progress(progress, static_cast<double>(d) / P.drawn.size(), t.ids[r]);
    });
  });
  bar.finish();
  write_ansur_realism(a, P, columns, set, measured, out);
  out.commit();
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
      "row per person) and OUT/summary.csv (RMSE and bias of both, and their ratio).\n"
      "ANSUR II files as --population (comma-separated, e.g. ansur2_female.csv,ansur2_male.csv): soldiers drawn\n"
      "uniformly (alternating files; --exclude a synth-db ANSUR database's subjects.csv leaves its subjectid out),\n"
      "morphed to sex, age, stature and weight, and every column of --girths (default: the 18 of\n"
      "docs/population.md) read as `measure --standard ansur2` does, against the regression on those four.");
  add_eval_population_options(cmd, *a);
  cmd->callback([a] {
    const auto files = cli::split_commas(a->population);
    if (!files.empty() && std::all_of(files.begin(), files.end(), [](const std::string& f) { return is_ansur_file(f); }))
      run_eval_population_ansur(*a);
    else
      run_eval_population(*a);
  });
}

}  // namespace bodymodel
