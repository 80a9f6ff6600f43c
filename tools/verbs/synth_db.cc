// bodymodel synth-db: a synthetic scan database with ground truth kept apart.
#include <fmt/format.h>

#include <filesystem>

#include "core/data_path.h"
#include "core/error.h"
#include "tools/console.h"
#include "population/ansur.h"
#include "population/ansur_fit.h"
#include "population/people.h"
#include "tools/synth/synthetic_scans.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {
struct SynthArgs {
  SyntheticDatabaseOptions options;
  std::string out;
  bool force = false, no_resume = false;
  std::string population_measurements = "height_cm,weight_kg,waist_iliac_cm,hips_cm,arm_circumference_cm";
};
}  // namespace

namespace {

void add_synth_db_options(CLI::App* cmd, SynthArgs& a) {
  auto& o = a.options;
  // Checked on the command line, before MakeHuman is loaded.
  cmd->add_option("--subjects", o.subjects, "Number of subjects (alternating female/male; with --population as drawn)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--poses-per-subject", o.poses_per_subject,
                  "Scans per subject besides the standard A-pose")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--seed", o.seed, "Random seed (the database is a function of it)")
      ->capture_default_str();
  cmd->add_option("--noise", o.scanner.noise_sigma_mm, "Scanner noise sigma, mm")
      ->capture_default_str();
  cmd->add_option("--landmark-noise", o.landmark_sigma_mm, "Landmark noise sigma, mm")
      ->capture_default_str();
  cmd->add_option("--min-points", o.scanner.min_points, "Minimum points per scan")
      ->capture_default_str();
  cmd->add_option("--perturbation", o.perturbation_deg,
                  "Sigma of the random joint perturbation added to each pose, degrees")
      ->capture_default_str();
  cmd->add_option("--population", o.population,
                  "A people file (NHANES, e.g. ../shared/data/anthropometry/nhanes_2017_2020_bmx_demo.csv, or\n"
                  "own columns, see fit-measurements): draw the subjects by survey weight (WTMECPRP) and make\n"
                  "each truth body with fit-measurements from the person's recorded values; subjects.csv\n"
                  "adds seqn and nhanes_* (the recorded values) beside the values measured on the truth mesh.\n"
                  "Or ANSUR II files, comma-separated (ansur2_female.csv,ansur2_male.csv): soldiers drawn\n"
                  "uniformly, alternating sexes, each body fitted with every MakeHuman body modifier to the\n"
                  "--population-measurements columns (default: the 18 of docs/population.md) and the survey's\n"
                  "other proportions; subjects.csv adds subjectid and the ANSUR columns measured on the truth mesh");
  cmd->add_option("--population-measurements", a.population_measurements,
                  "With --population: the recorded measurements the bodies are fitted to (comma-separated)")
      ->capture_default_str();
  cmd->add_option("--reuse-fits", o.fits,
                  "With --population: a fit-measurements --people batch's fit.csv; a drawn person fitted there to\n"
                  "the same measurements keeps that body instead of a new fit (sliders stored to 4 decimals)");
  cmd->add_flag("--truth-only", o.truth_only,
                "Write the truth bodies, poses and tables without simulating the scanner (what `build` reads;\n"
                "nothing for `register`): for model studies on many subjects");
  cmd->add_option("--jobs", o.threads, "Threads (0 = all cores)")->capture_default_str();
  cmd->add_option("--out", a.out, "Output folder")->required();
  cmd->add_flag("--force", a.force,
                "Write into an existing non-empty folder that does not hold this same database");
  cmd->add_flag("--no-resume", a.no_resume,
                "Make every scan again, even those an earlier run of the same database finished");
}

void run_synth_db(SynthArgs& a) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const bool non_empty = fs::exists(a.out, ec) && !fs::is_empty(a.out, ec);
  if (non_empty && !a.force && !fs::exists(fs::path(a.out) / "database.json", ec))
    throw InputError("output folder '" + a.out +
                     "' exists and is not empty (use --force to write into it)");
  a.options.resume = !a.no_resume;
  a.options.population_measurements = cli::split_commas(a.population_measurements);
  const auto files = cli::split_commas(a.options.population);
  const bool ansur = !files.empty() && std::all_of(files.begin(), files.end(), [](const std::string& f) { return is_ansur_file(f); });
  if (ansur) {
    // ANSUR II: the columns are the survey's; the NHANES default becomes the 18 of the accuracy bar.
    if (a.population_measurements == SynthArgs{}.population_measurements)
      a.options.population_measurements = default_ansur_columns();
    for (const auto& f : files) {
      const AnsurTable t = read_ansur(f, a.options.population_measurements);
      cli::info(fmt::format("population {}: {} soldiers; fitting {} columns", f, t.ids.size(),
                            a.options.population_measurements.size()));
    }
  } else if (!a.options.population.empty()) {
    validate_measurement_names(a.options.population_measurements);
    // The file is checked (columns, eligible people) before any folder is touched.
    const PeopleTable table = read_people(a.options.population);
    require_columns(table, {"sex", "age_years"});
    require_columns(table, a.options.population_measurements);
    PopulationFilter filter;
    filter.required = a.options.population_measurements;
    const EligibleSummary e = eligible_people(table, filter);
    if (e.eligible.empty())
      throw InputError(fmt::format("'{}': no adult has a sex, an age, a survey weight and {} ({} incomplete, "
                                   "{} under 18, {} without a weight)",
                                   a.options.population, a.population_measurements, e.incomplete, e.children,
                                   e.no_weight));
    if (!a.options.fits.empty()) check_stored_fits(a.options.fits);
    cli::info(fmt::format("population {}: {} adults eligible ({} incomplete rows, {} under 18, {} without a "
                          "survey weight); drawing {} by survey weight",
                          a.options.population, e.eligible.size(), e.incomplete, e.children, e.no_weight,
                          a.options.subjects));
  }
  const auto& o = a.options;
  cli::info(fmt::format("synth-db: {} subjects x {} scans, seed {}, noise {} mm, landmarks {} mm, "
                        "{} pillars, min {} points/scan",
                        o.subjects, o.poses_per_subject + 1, o.seed, o.scanner.noise_sigma_mm,
                        o.landmark_sigma_mm, o.scanner.pillars, o.scanner.min_points));
  cli::info("loading MakeHuman data from " + data_root().string());
  MakeHuman mh = MakeHuman::load();
  if (non_empty) {
    std::string difference;
    if (is_same_synthetic_database(mh, a.out, o, &difference)) {
      cli::info(o.resume ? "resuming the database in " + a.out + " (finished scans are kept)"
                         : "making every scan of " + a.out + " again (--no-resume)");
    } else if (!a.force) {
      throw InputError("output folder '" + a.out + "' holds another synth-db database (" +
                       difference + "; use --force to write into it)");
    } else {
      cli::info("writing into " + a.out + ": its database.json differs (" + difference +
                "), every scan is made again");
    }
  }
  cli::ProgressBar bar("synth-db");
  SyntheticDatabaseSummary s = generate_synthetic_database(mh, a.out, o, bar.callback());
  bar.finish(fmt::format("{} scans ({} kept from an earlier run)", s.scans.size(), s.skipped));
  if (s.removed_temporaries > 0)
    cli::info(fmt::format("removed {} temporaries left by a killed run", s.removed_temporaries));
  if (non_empty) cli::info(fmt::format("skipped {} existing scans", s.skipped));
  double hmin = 1e9, hmax = 0, wmin = 1e9, wmax = 0;
  long points = 0;
  for (auto& subj : s.subjects) {
    hmin = std::min(hmin, subj.height_cm), hmax = std::max(hmax, subj.height_cm);
    wmin = std::min(wmin, subj.weight_kg), wmax = std::max(wmax, subj.weight_kg);
  }
  for (auto& scan : s.scans) points += scan.points;
  fmt::print("database      {}\n", a.out);
  int females = 0, reached = 0, extrapolated = 0;
  for (auto& subj : s.subjects) {
    females += subj.sex == "female";
    reached += subj.fit_reached;
    extrapolated += subj.extrapolated;
  }
  fmt::print("subjects      {} ({} female, {} male)\n", s.subjects.size(), females, s.subjects.size() - females);
  if (!o.population.empty())
    fmt::print("population    {} eligible adults; {} drawn, {} fitted within 0.5 cm / 1 kg / 2 cm, {} in the "
               "extended space; fits {:.1f} s ({} reused from {})\n",
               s.eligible_people, s.subjects.size(), reached, extrapolated, s.fit_seconds, s.reused_fits,
               o.fits.empty() ? "no file" : o.fits);
  fmt::print("scans         {} (standard pose + {} of: {}); {} made now, {} kept\n", s.scans.size(),
             o.poses_per_subject, fmt::join(s.pose_pool, ", "), s.scans.size() - s.skipped,
             s.skipped);
  fmt::print("height        {:.1f} .. {:.1f} cm\n", hmin, hmax);
  fmt::print("weight        {:.1f} .. {:.1f} kg\n", wmin, wmax);
  fmt::print("points/scan   {:.0f} on average\n", double(points) / s.scans.size());
  fmt::print("time          {:.1f} s\n", s.seconds);
}

}  // namespace

BODYMODEL_VERB(add_synth_db_verb) {
  auto a = std::make_shared<SynthArgs>();
  auto* cmd = app.add_subcommand(
      "synth-db",
      "Generate a synthetic scan database: MakeHuman subjects, posed, scanned by a simulated\n"
      "4-pillar laser scanner (noise, holes, estimated normals), with ground truth apart.\n"
      "Writes OUT/subjects.csv, OUT/scans.csv, OUT/scans/<id>.ply + <id>.landmarks.json,\n"
      "OUT/truth/<id>.ply + <id>.pose.csv (evaluation only) and OUT/database.json.\n"
      "A rerun with the same settings keeps the scans an earlier (interrupted) run finished and\n"
      "makes the rest; the folder ends identical to a clean run.");
  add_synth_db_options(cmd, *a);
  cmd->callback([a] { run_synth_db(*a); });
}

}  // namespace bodymodel
