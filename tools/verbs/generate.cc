// bodymodel generate model.npz --count 200 --where sex=female --where weight_kg=65
//   --where height_cm=160..180 --seed 7 --out crowd/
#include <algorithm>
#include <numeric>
#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <sstream>

#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/mesh_io.h"
#include "core/plausibility.h"
#include "model/generate_crowd.h"
#include "model/morph.h"
#include "population/people.h"
#include "tools/pipeline/crowd_output.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct GenerateArgs {
  std::string model, out, format = "obj";
  std::vector<std::string> where;
  int count = 10;
  uint64_t seed = 1;
  double spread = 1.0;
  bool clamp = false, no_girths = false, force = false;
  std::string population, match = "sex,age_years,height_cm,weight_kg";
  int jobs = 0;
  int diversity_sample = kDiversitySample;
};

LabelCondition parse_where(const SemanticRegression& reg, const std::string& s, bool clamp) {
  auto [label, text] = model_cli::split_assignment(s, "--where");
  int i = reg.index(label);
  auto dots = text.find("..");
  if (dots != std::string::npos) {
    double lo = model_cli::parse_number(text.substr(0, dots), "--where " + label + " lower bound");
    double hi = model_cli::parse_number(text.substr(dots + 2), "--where " + label + " upper bound");
    if (!(lo < hi)) throw InputError(fmt::format("--where {}: empty range {}..{}", label, lo, hi));
    lo = model_cli::check_label_range(reg.labels[i], lo, clamp);
    hi = model_cli::check_label_range(reg.labels[i], hi, clamp);
    return LabelCondition::range(label, lo, hi);
  }
  double v = model_cli::check_label_range(reg.labels[i], model_cli::parse_label_value(label, text), clamp);
  return LabelCondition::exact(label, v);
}

// A population's --where: which people may be drawn (sex=female, age_years=30..50,
// height_cm=150..170, ...: the person's recorded values).
std::function<bool(const Person&)> person_filter(const std::vector<std::string>& where) {
  std::vector<std::function<bool(const Person&)>> tests;
  for (const auto& w : where) {
    auto [label, text] = model_cli::split_assignment(w, "--where");
    if (label == "sex") {
      const double v = model_cli::parse_label_value("sex", text);
      tests.push_back([v](const Person& p) { return (p.sex == Sex::male) == (v > 0.5); });
      continue;
    }
    const auto& names = recorded_measurement_names();
    if (label != "age_years" && std::find(names.begin(), names.end(), label) == names.end())
      throw InputError(fmt::format("--where {}: with --population, conditions are on the people's recorded values "
                                   "(sex, age_years, {})",
                                   label, fmt::join(names, ", ")));
    double lo, hi;
    const auto dots = text.find("..");
    if (dots != std::string::npos) {
      lo = model_cli::parse_number(text.substr(0, dots), "--where " + label + " lower bound");
      hi = model_cli::parse_number(text.substr(dots + 2), "--where " + label + " upper bound");
    } else {
      lo = hi = model_cli::parse_number(text, "--where " + label);
    }
    tests.push_back([label = label, lo, hi](const Person& p) {
      const double v = label == "age_years" ? p.age_years : p.measurement(label);
      return v >= lo && v <= hi;
    });
  }
  return [tests](const Person& p) {
    for (const auto& t : tests)
      if (!t(p)) return false;
    return true;
  };
}

// The weighted eligible population against the crowd's measured values: KS per sex.
void print_population_match(const PeopleTable& table, const std::vector<int>& eligible, const fs::path& labels) {
  const std::vector<CsvRecord> rows = read_csv_file(labels);
  if (rows.empty()) return;
  const std::vector<std::string>& header = rows[0].fields;
  auto col = [&](const std::string& name) {
    return static_cast<int>(std::find(header.begin(), header.end(), name) - header.begin());
  };
  std::map<std::string, std::map<std::string, std::vector<double>>> crowd;  // sex → label → values
  for (size_t k = 1; k < rows.size(); ++k) {
    const std::vector<std::string>& cells = rows[k].fields;
    if (cells.size() < header.size()) continue;
    for (const char* m : {"height_cm", "weight_kg"})
      if (!cells[col(m)].empty()) crowd[cells[col("sex")]][m].push_back(std::stod(cells[col(m)]));
  }
  for (const char* sex : {"female", "male"})
    for (const char* m : {"height_cm", "weight_kg"}) {
      std::vector<double> pop, w;
      for (int i : eligible) {
        const Person& p = table.people[i];
        if ((p.sex == Sex::male) != (std::string(sex) == "male")) continue;
        pop.push_back(p.measurement(m));
        w.push_back(p.survey_weight);
      }
      const auto& got = crowd[sex][m];
      if (got.empty() || pop.empty()) continue;
      fmt::print("population match       {} {}: KS {:.3f} between the {} bodies (measured) and the weighted "
                 "population ({} people)\n",
                 sex, m, ks_statistic(got, pop, w), got.size(), pop.size());
    }
}

}  // namespace

namespace {

void add_generate_options(CLI::App* cmd, GenerateArgs& a) {
  cmd->add_option("model", a.model, "Model (.npz from `bodymodel build`)")->required();
  cmd->add_option("--count", a.count, "Number of bodies")->capture_default_str()->check(CLI::Range(1, 100000));
  cmd->add_option("--where", a.where,
                  "LABEL=VALUE or LABEL=LO..HI, repeatable (sex=female|male); with --population a filter on\n"
                  "the people's recorded values (sex, age_years, height_cm, weight_kg, ...)");
  cmd->add_option("--population", a.population,
                  "A people file (NHANES or own columns, see fit-measurements): each body is a person drawn by\n"
                  "survey weight (WTMECPRP, seeded) and morphed to that person's --match labels; labels.csv\n"
                  "adds the person's seqn and recorded values (nhanes_*) beside the measured ones");
  cmd->add_option("--match", a.match,
                  "With --population: the person's labels each body is morphed to (comma-separated; add\n"
                  "waist_iliac_cm,hips_cm for the girths)")
      ->capture_default_str();
  // NonNegativeNumber: CLI11 would read -1 into the unsigned seed as 18446744073709551615.
  cmd->add_option("--seed", a.seed, "Random seed (the crowd is a function of it)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--spread", a.spread,
                                 "Scale of the random coefficients (1 = the data's spread; with --population the\n"
                                 "default is 0: each body is its person's typical body, the people give the variety)")
                     ->capture_default_str();
  cmd->add_option("--format", a.format, "obj or ply")->check(CLI::IsMember({"obj", "ply"}))->capture_default_str();
  cmd->add_flag("--no-girths", a.no_girths,
                "labels.csv without the girths and body fat (height, volume, weight only): faster, the "
                "girths' sections being a large share of a body's time");
  cmd->add_flag("--clamp", a.clamp, "Clamp values far outside the data to the data's range");
  cmd->add_option("--jobs", a.jobs, "Bodies generated in parallel (0 = all cores); the crowd does not depend on it")
      ->capture_default_str()
      ->check(CLI::Range(0, 256));
  cmd->add_flag("--force", a.force,
                "Replace a crowd generated in OUT with other settings (without it such a folder is refused; "
                "a rerun with the same settings skips the bodies already written)");
  cmd->add_option("--out", a.out, "Output folder")->required();
}

// The people a population crowd is made of: read, filtered by --where, drawn by survey weight.
struct DrawnPopulation {
  PeopleTable table;
  std::vector<int> eligible, drawn;
  std::vector<std::string> match;
};

DrawnPopulation draw_population(const GenerateArgs& a) {
  DrawnPopulation d;
  PeopleTable& table = d.table;
  std::vector<int>& eligible = d.eligible;
  std::vector<int>& drawn = d.drawn;
  std::vector<std::string>& match = d.match;
  table = read_people(a.population);
  match = cli::split_commas(a.match);
  std::vector<std::string> needed = {"sex", "age_years", "height_cm", "weight_kg"};
  for (const auto& m : match)
    if (m != "sex" && m != "age_years" && std::find(needed.begin(), needed.end(), m) == needed.end()) needed.push_back(m);
  require_columns(table, needed);
  PopulationFilter filter;
  filter.required = {"height_cm", "weight_kg"};
  for (const auto& m : match)
    if (m != "sex" && m != "age_years" && m != "height_cm" && m != "weight_kg") filter.required.push_back(m);
  const EligibleSummary e = eligible_people(table, filter);
  const auto keep = person_filter(a.where);
  for (int i : e.eligible)
    if (keep(table.people[i])) eligible.push_back(i);
  if (eligible.empty())
    throw InputError(fmt::format("'{}': no adult with a survey weight and {} passes the --where filters "
                                 "({} incomplete, {} under 18)",
                                 a.population, fmt::join(filter.required, ", "), e.incomplete, e.children));
  drawn = sample_population(table, eligible, a.count, a.seed);
  cli::info(fmt::format("population {}: {} eligible adults; {} drawn by survey weight", a.population,
                        eligible.size(), drawn.size()));
  return d;
}

// The crowd's figures: constraints, folds, diversity against the training subjects, plausibility.
void print_generate_summary(const GenerateArgs& a, const std::shared_ptr<const BodyModel>& model, Sex sex, int n,
                            const fs::path& out, const GenerateCrowdSummary& s, const CrowdOutputOptions& co) {
  // Diversity: mean pairwise RMS vertex distance (after rigid fit) of a sample of the crowd
  // (read back: skipped bodies are only on disk), against that of the model's training
  // subjects: the figure `build` stored in the model when it has one for this very model, else
  // the subjects decoded from their coefficients now (model/generate_crowd.h).
  const int k = std::min(n, a.diversity_sample);
  std::vector<Eigen::MatrixX3d> crowd(k);
  for (int i = 0; i < k; ++i) crowd[i] = read_mesh(out / s.files[i]).V;
  std::optional<SubjectDiversity> subj = stored_subject_diversity(*model, sex, a.diversity_sample);
  if (!subj) subj = subject_diversity(*model, sex, a.diversity_sample, a.jobs);
  fmt::print("bodies                 {} ({} generated, {} skipped as already written)\n", n, s.generated, s.skipped);
  fmt::print("constraints met        {} of {} (as measured on each output)\n", s.constraints_met, n);
  fmt::print("flipped triangles      {} in total, at most {} in a body ({:.4f}% of all triangles), against the "
             "template after a rigid fit\n",
             s.flipped_triangles, s.max_flipped_triangles,
             100.0 * s.flipped_triangles / (double(n) * model->tmpl->triangle_count()));
  {
    std::vector<int> b = s.flipped_before_repair;
    std::sort(b.begin(), b.end());
    const int total = std::accumulate(b.begin(), b.end(), 0);
    if (!b.empty())
      fmt::print("fold repair            {} flipped triangles repaired after decoding: median {}, at most {} in a body\n",
                 total, 0.5 * (b[(b.size() - 1) / 2] + b[b.size() / 2]), b.back());
  }
  double crowd_diversity = 0;
  if (a.jobs > 0) {
    tbb::task_arena arena(a.jobs);
    arena.execute([&] { crowd_diversity = mean_pairwise_distance(crowd); });
  } else {
    crowd_diversity = mean_pairwise_distance(crowd);
  }
  fmt::print("diversity              mean pairwise RMS vertex distance {:.1f} mm (first {} bodies)\n",
             crowd_diversity, k);
  fmt::print("                       vs {:.1f} mm between the model's {} training subjects{}\n",
             subj->mean_pairwise_mm, subj->subjects, sex == Sex::unknown ? "" : " of that sex");
  {
    std::vector<int> si = s.self_intersections;
    std::vector<double> rp = s.roughness_p95;
    std::sort(si.begin(), si.end());
    std::sort(rp.begin(), rp.end());
    if (!si.empty())
      fmt::print("self-intersections     median {} triangle pairs, at most {}; {} of {} bodies have none\n",
                 0.5 * (si[(si.size() - 1) / 2] + si[si.size() / 2]), si.back(),
                 std::count(si.begin(), si.end(), 0), si.size());
    if (!rp.empty())
      fmt::print("roughness p95          median {:.1f} deg, at most {:.1f} deg ({})\n", rp[rp.size() / 2], rp.back(),
                 co.roughness_region.empty() ? "every vertex: the model has no rig" : "trunk and limbs");
  }
}

void run_generate(GenerateArgs& a, CLI::App* cmd) {
  // A population is read and drawn before the model is loaded: bad input fails fast.
  DrawnPopulation d;
  if (!a.population.empty()) d = draw_population(a);
  const PeopleTable& table = d.table;
  const std::vector<int>& eligible = d.eligible;
  const std::vector<int>& drawn = d.drawn;
  const std::vector<std::string>& match = d.match;
  auto model = std::make_shared<const BodyModel>(model_cli::load_model_for_cli(a.model));
  const SemanticRegression& reg = model->shape.regression;
  std::vector<LabelCondition> cond;
  CrowdOutputOptions co;
  if (a.population.empty()) {
    for (auto& w : a.where) cond.push_back(parse_where(reg, w, a.clamp));
  } else {
    for (const auto& m : match) reg.index(m);  // every matched label must be the model's
    co.population_source = a.population;
    co.recorded_names = recorded_measurement_names();
    for (int i : drawn) {
      const Person& p = table.people[i];
      CrowdPerson c;
      c.id = p.id;
      c.sex = p.sex == Sex::male ? "male" : "female";
      c.recorded = p.measurements;
      for (const auto& m : match) {
        const int l = reg.index(m);
        double v = m == "sex" ? (p.sex == Sex::male ? 1.0 : 0.0) : m == "age_years" ? p.age_years : p.measurement(m);
        // Values outside the model's data are clamped to it (silently: a person is not a typo).
        if (m != "sex") v = std::clamp(v, reg.labels[l].min, reg.labels[l].max);
        c.conditions.push_back(LabelCondition::exact(m, v));
      }
      co.people.push_back(std::move(c));
    }
  }
  if (!model->rig.empty())
    co.roughness_region = trunk_and_limbs_region(model->rig.bone_names, model->rig.parents, model->rig.weights);
  // A population crowd's variety comes from its people; random coefficients on top roughen the
  // bodies (200 bodies of a 200-person model: self-intersection median 16 at spread 1, 0 at 0).
  co.crowd.generate.spread = !a.population.empty() && cmd->get_option("--spread")->count() == 0 ? 0.0 : a.spread;
  co.crowd.generate.measure_girths = !a.no_girths;
  co.crowd.seed = a.seed;
  co.crowd.threads = a.jobs;
  co.format = a.format;
  co.force = a.force;
  Sex sex = Sex::unknown;
  for (auto& c : cond)
    if (c.label == "sex") sex = c.lo < 0.5 ? Sex::female : Sex::male;
  const int n = a.population.empty() ? a.count : static_cast<int>(drawn.size());
  const fs::path out(a.out);
  GenerateCrowdSummary s;
  {
    cli::ProgressBar bar("generate");
    s = write_crowd(model, cond, n, out, co, bar.callback());
    bar.finish(fmt::format("{} bodies in {:.1f} s ({:.1f}/s)", s.generated, s.seconds,
                           s.generated / std::max(s.seconds, 1e-9)));
  }
  if (s.skipped > 0) cli::info(fmt::format("skipped {} existing (complete bodies of an earlier run with the same settings)", s.skipped));
  print_generate_summary(a, model, sex, n, out, s, co);
  if (!a.population.empty()) print_population_match(table, eligible, out / "labels.csv");
  if (s.generated > 0)
    fmt::print("speed                  {:.1f} bodies/s including writing meshes\n", s.generated / std::max(s.seconds, 1e-9));
  cli::info("wrote " + (out / "labels.csv").string());
  // A body that misses a condition is a failed item of the batch: everything stays written
  // (and is skipped on a rerun), but the exit code says the crowd is not what was asked for.
  if (s.constraints_met < n)
    throw InputError(fmt::format("{} of {} bodies did not meet every condition as measured (constraints_met "
                                 "is 0 in their rows of '{}'); the bodies were written",
                                 n - s.constraints_met, n, (out / "labels.csv").string()));
}

}  // namespace

BODYMODEL_VERB(add_model_generate_verb) {
  auto a = std::make_shared<GenerateArgs>();
  auto* cmd = app.add_subcommand(
      "generate",
      "Generate random bodies from the shape-only model (§5.2): coefficients ~ N(0, eigenvalues)\n"
      "(or the chosen sex's subjects), then the --where conditions are enforced as MEASURED on\n"
      "each output (model/morph.h). Writes OUT/body_NNN.obj, OUT/labels.csv with the measured\n"
      "labels of every body and OUT/generate.json with the settings. Body k depends only on the\n"
      "seed and k. A rerun with the same settings skips the bodies already written (tools/pipeline/crowd_output.h).");
  add_generate_options(cmd, *a);
  cmd->callback([a, cmd] { run_generate(*a, cmd); });
}

}  // namespace bodymodel
