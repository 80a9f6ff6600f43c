// bodymodel shape-space [--people ansur2_female.csv,ansur2_male.csv] [--sample 150] [--components 20] --out space.json
#include <fmt/format.h>

#include <filesystem>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/shape_space_file.h"
#include "population/ansur.h"
#include "population/shape_space_fit.h"
#include "tools/console.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct ShapeSpaceArgs {
  std::string people, out;
  int sample = 150, components = 20, jobs = 0;
  uint64_t seed = 1;
};

void run_shape_space(const ShapeSpaceArgs& a) {
  if (a.sample < 0) throw InputError(fmt::format("--sample must not be negative, got {}", a.sample));
  if (a.components < 1) throw InputError(fmt::format("--components must be at least 1, got {}", a.components));
  std::vector<std::string> files = cli::split_commas(a.people);
  if (files.empty())
    for (const char* f : {"ansur2_female.csv", "ansur2_male.csv"})
      files.push_back(data_file(fs::path("anthropometry") / "ansur2" / f).string());
  std::vector<AnsurTable> tables;
  for (const auto& f : files) {
    if (!is_ansur_file(f)) throw InputError(f + ": not an ANSUR II file (its first column must be subjectid)");
    tables.push_back(read_ansur(f));
  }
  cli::info("loading MakeHuman data from " + data_root().string());
  const MakeHuman mh = MakeHuman::load();
  ShapeSpaceFitOptions o;
  o.per_table = a.sample;
  o.components = a.components;
  o.seed = a.seed;
  o.jobs = a.jobs;
  cli::info(fmt::format("fitting {} soldiers of each of {} file(s) to ANSUR's default columns; {} components",
                        a.sample > 0 ? std::to_string(a.sample) : std::string("all"), files.size(), a.components));
  cli::ProgressBar bar("shape-space");
  const ProgressCallback progress = bar.callback();
  o.progress = [&](int d, int n) { report_progress(progress, double(d) / n, ""); };
  const ShapeSpaceFitRun run = ansur_shape_space(mh, tables, o);
  write_text_file(a.out, shape_space_json(run.space));
  bar.finish(fmt::format("{} bodies in {:.1f} s", run.space.people, run.seconds));
  fmt::print("bodies      {} ({} kept a flipped triangle)\ncomponents  {} of {} parameters, {:.1f} % of the "
             "variance\nsd          {:.3f} … {:.3f}\nwrote       {}\n",
             run.space.people, run.flipped_people, run.space.components(), run.space.parameters.size(),
             100 * run.space.explained, run.space.sd.maxCoeff(), run.space.sd.minCoeff(), a.out);
}

}  // namespace

BODYMODEL_VERB(add_shape_space_verb) {
  auto a = std::make_shared<ShapeSpaceArgs>();
  auto* cmd = app.add_subcommand(
      "shape-space",
      "Learn a shape space from real people for registration (register/register-mesh --shape-space):\n"
      "ANSUR II soldiers are fitted as MakeHuman bodies to 18 of their measurements (every body\n"
      "modifier, as fit-measurements --people does), and the principal components of their fitted\n"
      "parameters (macro sliders, measurement and body-shape modifiers) are written as JSON with the\n"
      "soldiers' standard deviation along each (the registration's prior). See docs/registration.md.\n"
      "Example: bodymodel shape-space --sample 150 --out ansur-space.json");
  cmd->add_option("--people", a->people,
                  "ANSUR II files, comma-separated (default: both of the data folder's, women and men)");
  cmd->add_option("--sample", a->sample, "Soldiers drawn at random from each file (0 = all)")->capture_default_str();
  cmd->add_option("--components", a->components, "Principal components kept")->capture_default_str();
  cmd->add_option("--seed", a->seed, "Seed of --sample")->capture_default_str();
  cmd->add_option("--jobs", a->jobs, "People fitted in parallel (0 = all cores)")->capture_default_str();
  cmd->add_option("--out", a->out, "Output shape-space file (.json)")->required();
  cmd->callback([a] { run_shape_space(*a); });
}

}  // namespace bodymodel
