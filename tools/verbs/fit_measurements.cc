// bodymodel fit-measurements --sex female --age 40 --set height_cm=165 --set weight_kg=80 ... --out body.obj
// bodymodel fit-measurements --people people.csv [--sample 500 --seed 1] --out OUT/
#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <filesystem>
#include <map>
#include <mutex>
#include <random>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/file_names.h"
#include "core/io/mesh_io.h"
#include "population/ansur.h"
#include "population/ansur_fit.h"
#include "population/fit_measurements.h"
#include "population/people.h"
#include "tools/console.h"
#include "tools/pipeline/output_folder.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct FitArgs {
  std::string sex, people, out, space = "extended", ethnicity;
  double age = -1;
  std::vector<std::string> set;
  std::string measurements, columns, prior;
  int sample = 0, jobs = 0;
  uint64_t seed = 1;
  bool allow_children = false, skip_incomplete = false, force = false;
};

// The measurement definitions for --help.
std::string definitions_help() {
  std::string s = "Measurements (names for --set; all measured on the output mesh, core/measure.h):\n";
  const auto& fit = fittable_measurements();
  for (const auto& d : measurement_definitions())
    if (std::find(fit.begin(), fit.end(), d.name) != fit.end())
      s += fmt::format("  {:<21} {}\n", d.name, d.definition);
  s += "Template landmarks (hm08 vertex indices, core/landmarks.h): iliac crest 4272+4395, crotch 4372,\n"
       "acromion 1557, olecranon 3357, inguinal crease 4339, top of patella 4594, upper-arm ring of 20.";
  return s;
}

std::array<double, 3> parse_ethnicity(const std::string& e) {
  if (e.empty() || e == "mixed") return {1.0 / 3, 1.0 / 3, 1.0 / 3};
  if (e == "african") return ethnic_prior(4);
  if (e == "asian") return ethnic_prior(6);
  if (e == "caucasian") return ethnic_prior(3);
  if (e == "hispanic") return ethnic_prior(1);
  throw InputError("--ethnicity must be african, asian, caucasian, hispanic or mixed (got '" + e + "')");
}

FitMeasurementsOptions fit_options(const FitArgs& a) {
  FitMeasurementsOptions o;
  o.extended_space = a.space == "extended";
  return o;
}

std::string csv_number(double v, int decimals = 2) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, decimals) : std::string();
}

std::string fit_csv_header(const MakeHuman& mh) {
  std::string h = "id,mesh,line,sex,age_years,ethnicity,reached,extrapolated,reason,fitted";
  for (const auto& m : recorded_measurement_names()) h += fmt::format(",{0}_recorded,{0}_measured,{0}_residual", m);
  for (const char* s : {"gender", "age", "muscle", "weight", "height", "proportions", "cup", "firmness", "african",
                        "asian", "caucasian"})
    h += fmt::format(",slider_{}", s);
  for (const auto& m : mh.measure_modifier_names()) h += ",modifier_" + m;
  h += ",roughness_p95_deg,roughness_max_deg,self_intersections,iterations,evaluations,seconds";
  return h;
}

// The person's id as the file has it, and the mesh written for them (ids need not be unique
// nor plain file names).
std::string fit_csv_row(const Person& p, const std::string& mesh, const PersonSpec& spec,
                        const MeasurementFit& f) {
  std::vector<std::string> fitted;
  for (const auto& t : spec.targets) fitted.push_back(t.name);
  std::string r = fmt::format("{},{},{},{},{},{},{},{},{},{}", csv_field(p.id), csv_field(mesh), p.line,
                              p.sex == Sex::male ? "male" : "female", csv_number(p.age_years, 0), p.ethnicity,
                              f.reached ? 1 : 0, f.extrapolated ? 1 : 0, csv_field(f.reason), fmt::join(fitted, ";"));
  for (const auto& m : recorded_measurement_names()) {
    const double rec = p.measurement(m), got = measurement_value(f.measured, m);
    r += fmt::format(",{},{},{}", csv_number(rec), csv_number(got), csv_number(got - rec));
  }
  const MacroSettings& s = f.sliders;
  for (double v : {s.gender, s.age, s.muscle, s.weight, s.height, s.proportions, s.cup, s.firmness, s.african,
                   s.asian, s.caucasian})
    r += "," + csv_number(v, 4);
  for (Eigen::Index k = 0; k < f.modifiers.size(); ++k) r += "," + csv_number(f.modifiers(k), 4);
  r += fmt::format(",{},{},{},{},{},{}", csv_number(f.roughness.p95_deg), csv_number(f.roughness.max_deg),
                   f.self_intersections, f.iterations, f.evaluations, csv_number(f.seconds, 2));
  return r;
}

void run_single(const FitArgs& a) {
  if (a.sex != "female" && a.sex != "male") throw InputError("--sex female|male is required (or --people FILE)");
  if (a.age < 0) throw InputError("--age YEARS is required (or --people FILE)");
  if (a.age < 18 && !a.allow_children)
    throw InputError(fmt::format("--age {:g} is under 18: MakeHuman's children need --allow-children", a.age));
  if (a.out.empty()) throw InputError("--out FILE.obj|ply is required");
  PersonSpec spec;
  spec.sex = a.sex == "male" ? Sex::male : Sex::female;
  spec.age_years = a.age;
  spec.ethnic_prior = parse_ethnicity(a.ethnicity);
  for (const auto& s : a.set) {
    auto [name, text] = model_cli::split_assignment(s, "--set");
    spec.targets.push_back({name, model_cli::parse_number(text, "--set " + name)});
  }
  if (spec.targets.empty()) throw InputError("nothing to fit: give at least one --set NAME=VALUE");
  validate_measurement_targets(spec.targets);  // before loading anything
  cli::info("loading MakeHuman data from " + data_root().string());
  const MakeHuman mh = MakeHuman::load();
  const MeasurementFit f = fit_measurements(mh, spec, fit_options(a));
  write_mesh(a.out, f.V, mh.body_faces());
  fmt::print("{:<22} {:>9} {:>9} {:>9}\n", "measurement", "target", "achieved", "residual");
  for (const auto& r : f.residuals)
    fmt::print("{:<22} {:>9.2f} {:>9.2f} {:>+9.2f}  {}\n", r.name, r.target, r.achieved, r.residual(),
               r.within ? "ok" : "MISSED");
  fmt::print("sliders     {}\n", f.sliders_text());
  std::string mods;
  for (Eigen::Index k = 0; k < f.modifiers.size(); ++k)
    if (std::abs(f.modifiers(k)) >= 0.005) mods += fmt::format(" {}={:+.2f}", mh.measure_modifier_names()[k], f.modifiers(k));
  fmt::print("modifiers  {}\n", mods.empty() ? " (none)" : mods);
  fmt::print("space       {}{}\n", a.space, f.extrapolated ? " (the body uses sliders beyond MakeHuman's range)" : "");
  fmt::print("roughness   p95 {:.1f} deg, max {:.1f} deg (trunk and limbs); {} self-intersecting triangle pairs\n",
             f.roughness.p95_deg, f.roughness.max_deg, f.self_intersections);
  fmt::print("fit         {} iterations, {} bodies measured, {:.1f} s\n", f.iterations, f.evaluations, f.seconds);
  cli::info("wrote " + a.out);
  if (!f.reached)
    throw InputError("not every measurement was reached (" + f.reason + "); the closest body was written to '" +
                     a.out + "'");
}

void run_batch(const FitArgs& a) {
  if (!a.sex.empty() || a.age >= 0 || !a.set.empty())
    throw InputError("--people fits the file's people: --sex, --age and --set belong to a single fit");
  if (a.out.empty()) throw InputError("--out FOLDER is required");
  const PeopleTable table = read_people(a.people);
  require_columns(table, {"sex", "age_years", "height_cm", "weight_kg"});
  std::vector<std::string> measurements;
  if (a.measurements.empty()) {
    for (const char* m : {"height_cm", "weight_kg", "waist_iliac_cm", "hips_cm", "arm_circumference_cm"})
      if (table.has(m)) measurements.push_back(m);
  } else {
    measurements = cli::split_commas(a.measurements);
    validate_measurement_names(measurements);
    for (const auto& m : measurements)
      if (std::find(recorded_measurement_names().begin(), recorded_measurement_names().end(), m) ==
          recorded_measurement_names().end())
        throw InputError(fmt::format("--measurements: a people file has no column for '{}' (it records {})", m,
                                     fmt::join(recorded_measurement_names(), ", ")));
    require_columns(table, measurements);
  }
  std::vector<int> rows;
  if (a.sample > 0) {
    PopulationFilter filter;
    filter.allow_children = a.allow_children;
    filter.required = measurements;
    const EligibleSummary e = eligible_people(table, filter);
    cli::info(fmt::format("{}: {} people eligible ({} incomplete, {} under 18, {} without a survey weight)",
                          table.source, e.eligible.size(), e.incomplete, e.children, e.no_weight));
    rows = sample_population(table, e.eligible, a.sample, a.seed);
  } else {
    const PeopleSelection s = select_people(table, measurements, a.allow_children, a.skip_incomplete);
    if (s.incomplete + s.children > 0)
      cli::info(fmt::format("skipped {} incomplete rows and {} under 18", s.incomplete, s.children));
    rows = s.rows;
  }
  // Every person's targets are checked before anything is fitted or written.
  std::vector<PersonSpec> specs;
  std::vector<std::string> ids;
  for (int i : rows) {
    const Person& p = table.people[i];
    PersonSpec spec = person_spec(p, measurements);
    try {
      validate_measurement_targets(spec.targets);
    } catch (const InputError& e) {
      throw InputError(fmt::format("'{}' line {} (person {}): {}", table.source, p.line, p.id, e.what()));
    }
    specs.push_back(std::move(spec));
    ids.push_back(p.id);
  }
  // Ids are data: a mesh is named after one only through unique_file_names (never outside the
  // folder, never two people on one file).
  const std::vector<std::string> stems = unique_file_names(ids, "person");
  StagedFolder out(a.out, a.force);
  cli::info(fmt::format("fitting {} people ({}; {} space) into {}", rows.size(), fmt::join(measurements, ", "),
                        a.space, a.out));
  cli::info("loading MakeHuman data from " + data_root().string());
  const MakeHuman mh = MakeHuman::load();
  const FitMeasurementsOptions o = fit_options(a);
  std::vector<std::string> lines(rows.size());
  std::vector<char> reached(rows.size(), 0);
  std::atomic<int> done{0};
  std::mutex mutex;
  cli::ProgressBar bar("fit-measurements");
  const ProgressCallback progress = bar.callback();
  tbb::task_arena arena(a.jobs > 0 ? a.jobs : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(0, static_cast<int>(rows.size()), [&](int k) {
      const MeasurementFit f = fit_measurements(mh, specs[k], o);
      write_mesh(out / (stems[k] + ".obj"), f.V, mh.body_faces());
      lines[k] = fit_csv_row(table.people[rows[k]], stems[k] + ".obj", specs[k], f);
      reached[k] = f.reached;
      const int d = ++done;
      std::lock_guard<std::mutex> lock(mutex);
      report_progress(progress, static_cast<double>(d) / rows.size(), stems[k]);
    });
  });
  std::string csv = fit_csv_header(mh) + "\n";
  for (const auto& l : lines) csv += l + "\n";
  write_text_file(out / "fit.csv", csv);
  int ok = 0;
  for (char r : reached) ok += r;
  bar.finish(fmt::format("{} people, {} reached every measurement", rows.size(), ok));
  out.commit();
  fmt::print("people      {}\nreached     {} ({:.1f} %)\nnot reached {} (reason per person in {}/fit.csv)\n", rows.size(),
             ok, 100.0 * ok / rows.size(), rows.size() - ok, a.out);
}

std::string ansur_csv(const AnsurFitRun& run, const AnsurTable& table, const std::vector<std::string>& stems) {
  const auto& names = run.people.front().fit.names;
  std::string csv = "subject,mesh,iterations,evaluations,retries,seconds,flipped_triangles,self_intersections";
  for (const auto& n : names) csv += fmt::format(",{0}_given,{0}_target,{0}_measured,{0}_survey", n);
  csv += "\n";
  for (size_t i = 0; i < run.people.size(); ++i) {
    const AnsurFitRow& p = run.people[i];
    csv += fmt::format("{},{}.obj,{},{},{},{:.2f},{},{}", csv_field(p.id), csv_field(stems[i]), p.fit.iterations,
                       p.fit.evaluations, p.fit.retries, p.fit.seconds, p.fit.flipped_triangles,
                       p.fit.self_intersections);
    for (size_t k = 0; k < names.size(); ++k) {
      const auto it = std::find(table.columns.begin(), table.columns.end(), names[k]);
      const double survey = it == table.columns.end() ? NAN : table.values(p.row, it - table.columns.begin());
      csv += fmt::format(",{},{},{},{}", int(p.fit.given[k]), csv_number(p.fit.target(k)),
                         csv_number(p.fit.measured(k)), csv_number(survey));
    }
    csv += "\n";
  }
  return csv;
}

void print_ansur_summary(const AnsurFitRun& run) {
  fmt::print("{:<28} {:>6} {:>9} {:>10} {:>10} {:>9} {:>6}\n", "measurement", "given", "within", "rmse body",
             "rmse regr", "bias", "ratio");
  for (const auto& s : run.summary)
    fmt::print("{:<28} {:>6} {:>8.1f}% {:>10.2f} {:>10} {:>+9.2f} {:>6}\n", s.name, s.given ? "yes" : "no",
               100 * s.within, s.rmse_body, s.given ? "" : fmt::format("{:.2f}", s.rmse_regression), s.mean_error,
               s.given ? "" : fmt::format("{:.2f}", s.rmse_body / s.rmse_regression));
  fmt::print("people      {} in {:.1f} s ({:.2f} people/s); {} with a flipped triangle, {} with more "
             "self-intersecting triangle pairs than MakeHuman's own body (the default body has {}; {} pushed apart "
             "where they crossed)\n",
             run.people.size(), run.seconds, run.people.size() / run.seconds, run.flipped_people,
             run.self_intersecting_people, run.template_self_intersections, run.pushed_apart_people);
}

// fit-measurements --people ANSUR.csv: one body per soldier from the chosen columns, the prior and
// the regression baseline learned from the other soldiers of that sex (population/ansur_fit.h).
void run_ansur_batch(const FitArgs& a) {
  if (!a.measurements.empty()) throw InputError("an ANSUR file takes --columns (its own column names), not --measurements");
  const std::vector<std::string> given = a.columns.empty() ? default_ansur_columns() : cli::split_commas(a.columns);
  const AnsurTable table = read_ansur(a.people, given);
  const int male = table.male.empty() ? 1 : table.male[0];
  const fs::path prior_path =
      a.prior.empty() ? data_file(fs::path("anthropometry") / "ansur2" / (male ? "ansur2_male.csv" : "ansur2_female.csv"))
                      : fs::path(a.prior);
  const AnsurTable prior = fs::equivalent(prior_path, a.people) ? table : read_ansur(prior_path);
  AnsurFitOptions o;
  o.given = given;
  o.jobs = a.jobs;
  if (a.sample > 0) {
    std::vector<int> all(table.male.size());
    for (size_t r = 0; r < all.size(); ++r) all[r] = static_cast<int>(r);
    std::mt19937_64 rng(a.seed);
    std::shuffle(all.begin(), all.end(), rng);
    all.resize(std::min<size_t>(all.size(), a.sample));
    std::sort(all.begin(), all.end());
    o.rows = all;
  }
  StagedFolder out(a.out, a.force);
  cli::info("loading MakeHuman data from " + data_root().string());
  const MakeHuman mh = MakeHuman::load();
  const MeasurementSet set = ansur_measurement_set(mh);
  const ProportionFitter fitter(mh, set);
  cli::ProgressBar bar("fit-measurements");
  const ProgressCallback progress = bar.callback();
  o.progress = [&](int d, int n) { report_progress(progress, double(d) / n, ""); };
  cli::info(fmt::format("fitting {} soldiers of {} to {} columns; prior: {}", o.rows.empty() ? table.ids.size() : o.rows.size(),
                        a.people, given.size(), prior_path.string()));
  const AnsurFitRun run = fit_ansur_rows(fitter, set, table, prior, o, true);
  std::vector<std::string> ids;
  for (const auto& p : run.people) ids.push_back(p.id);
  const std::vector<std::string> stems = unique_file_names(ids, "subject");
  for (size_t i = 0; i < run.people.size(); ++i) write_mesh(out / (stems[i] + ".obj"), run.people[i].fit.V, mh.body_faces());
  write_text_file(out / "fit.csv", ansur_csv(run, table, stems));
  bar.finish(fmt::format("{} soldiers", run.people.size()));
  out.commit();
  print_ansur_summary(run);
}

}  // namespace

BODYMODEL_VERB(add_fit_measurements_verb) {
  auto a = std::make_shared<FitArgs>();
  auto* cmd = app.add_subcommand(
      "fit-measurements",
      "A MakeHuman body from a person's measurements: finds the macro sliders (gender, age, muscle,\n"
      "weight, height, proportions, cup, firmness, ethnic weights) and the 20 measurement modifiers\n"
      "(targets/measure/) whose body, MEASURED on the output mesh, has the given values; prints target,\n"
      "achieved and residual per measurement. A person the slider space cannot reach gets the closest\n"
      "body and the reason (exit code 2 for a single fit; a per-person reason in fit.csv for --people).\n"
      "Batch: --people FILE (NHANES column names accepted: SEQN, RIAGENDR, RIDAGEYR, BMXHT, BMXWT,\n"
      "BMXWAIST, BMXHIP, BMXARMC, BMXARML, BMXLEG, WTMECPRP, RIDRETH3) writes OUT/<SEQN or row>.obj and\n"
      "OUT/fit.csv (id, mesh file, recorded, measured and residual per measurement, sliders, roughness).\n"
      "An id that is no plain file name (separators, '..', control or non-UTF-8 bytes) or repeats\n"
      "gets a sanitised, unique mesh name; fit.csv's mesh column says which.\n\n" +
          definitions_help());
  cmd->add_option("--sex", a->sex, "female|male (single fit)")->check(CLI::IsMember({"female", "male"}));
  cmd->add_option("--age", a->age, "Age in years (single fit)");
  cmd->add_option("--set", a->set, "NAME=VALUE, repeatable: height_cm=165 weight_kg=80 waist_iliac_cm=95 hips_cm=108 ...");
  cmd->add_option("--ethnicity", a->ethnicity,
                  "Prior of MakeHuman's ethnic sliders: african, asian, caucasian, hispanic or mixed (default)");
  cmd->add_option("--people", a->people, "Batch: a people file (NHANES or our column names, see above)");
  cmd->add_option("--measurements", a->measurements,
                  "Batch: comma-separated measurements to fit (default: those of height_cm, weight_kg,\n"
                  "waist_iliac_cm, hips_cm, arm_circumference_cm the file has; the two lengths are not\n"
                  "fitted by default: NHANES takes them seated and bent, see docs/population.md)");
  cmd->add_option("--columns", a->columns,
                  "ANSUR II file: comma-separated columns the body is fitted to (default: the 18 of\n"
                  "docs/population.md: stature, weightkg, chest, waist, buttock, thigh, calf, biceps, neck base and\n"
                  "shoulder circumference, biacromial and hip breadth, chest depth, acromial, crotch, iliocristale\n"
                  "and knee height, sleeve outseam); the others take the values real soldiers with these have");
  cmd->add_option("--prior", a->prior,
                  "ANSUR II file the population prior is learned from (default: the data folder's file of the\n"
                  "same sex; the soldiers being fitted are left out of it)");
  cmd->add_option("--sample", a->sample, "Batch: draw this many adults by survey weight (WTMECPRP) instead of every row")
      ->check(CLI::Range(1, 1000000));
  cmd->add_option("--seed", a->seed, "Seed of --sample")->capture_default_str();
  cmd->add_option("--space", a->space,
                  "extended (sliders beyond MakeHuman's range where bodies stay smooth) or standard")
      ->check(CLI::IsMember({"extended", "standard"}))
      ->capture_default_str();
  cmd->add_flag("--allow-children", a->allow_children, "Accept ages under 18 (MakeHuman's child shapes)");
  cmd->add_flag("--skip-incomplete", a->skip_incomplete, "Batch: skip rows without sex, age or a fitted measurement, and children");
  cmd->add_option("--jobs", a->jobs, "Batch: people fitted in parallel (0 = all cores)")->capture_default_str();
  cmd->add_option("--out", a->out, "Output mesh (single) or folder (batch)")->required();
  cmd->add_flag("--force", a->force, "Batch: replace an existing output folder");
  cmd->callback([a] {
    if (a->people.empty()) {
      if (a->sample > 0 || !a->measurements.empty() || a->skip_incomplete)
        throw InputError("--sample, --measurements and --skip-incomplete need --people FILE");
      run_single(*a);
    } else if (is_ansur_file(a->people)) {
      run_ansur_batch(*a);
    } else {
      if (!a->columns.empty() || !a->prior.empty()) throw InputError("--columns and --prior need an ANSUR II file (--people)");
      run_batch(*a);
    }
  });
}

}  // namespace bodymodel
