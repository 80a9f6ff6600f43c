// bodymodel sweep model.npz --label weight_kg --values 45,60,75,90,105,120,135,150 --set sex=female
//   --set height_cm=165 --out sweep/
#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <filesystem>
#include <mutex>

#include "core/body_size.h"
#include "core/data_path.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/mesh_io.h"
#include "core/plausibility.h"
#include "model/morph.h"
#include "population/fit_measurements.h"
#include "tools/console.h"
#include "tools/pipeline/output_folder.h"
#include "tools/render/render.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct SweepArgs {
  std::string model, in, out, label, values, change;
  std::vector<std::string> set, keep;
  bool no_reference = false, force = false, clamp = false;
  double bmi = 0;
  int jobs = 0;
};

struct SweepRow {
  double value = 0;
  MorphSummary summary;
  PlausibilityReport plausibility;
  int flipped = 0, flipped_before = 0;  // after / before the fold repair
  std::string file;
};

}  // namespace

namespace {

void add_sweep_options(CLI::App* cmd, SweepArgs& a) {
  cmd->add_option("model", a.model, "Model (.npz from `bodymodel build`)")->required();
  cmd->add_option("--label", a.label, "The swept label (weight_kg, height_cm, ...)")->required();
  cmd->add_option("--values", a.values, "Comma-separated values of the label")->required();
  cmd->add_option("--set", a.set, "LABEL=VALUE held for every body (sex=female, height_cm=165, ...)");
  cmd->add_option("--keep", a.keep, "LABEL kept at the --in body's value, repeatable");
  cmd->add_option("--bmi", a.bmi,
                  "With --label height_cm: each body's weight_kg is this BMI times its height² (a height sweep "
                  "at constant BMI)");
  cmd->add_option("--in", a.in, "Start body (model topology); default the model's mean body");
  cmd->add_option("--change", a.change, "smallest or likely (default: likely from the mean, smallest with --in)")
      ->check(CLI::IsMember({"smallest", "likely"}));
  cmd->add_flag("--no-reference", a.no_reference, "Skip the nearest-MakeHuman roughness reference (a fit per body)");
  cmd->add_flag("--clamp", a.clamp, "Clamp values far outside the data to the data's range");
  cmd->add_option("--jobs", a.jobs, "Bodies in parallel (0 = all cores)")->capture_default_str();
  cmd->add_option("--out", a.out, "Output folder")->required();
  cmd->add_flag("--force", a.force, "Replace an existing output folder");
}

// sweep.csv, and the same table on the terminal.
std::string sweep_table(const SweepArgs& a, const std::vector<SweepRow>& rows) {
  std::string csv =
      "value,file,converged,height_cm,weight_kg,waist_iliac_cm,hips_cm,roughness_p95_deg,roughness_max_deg,"
      "reference_p95_deg,reference_max_deg,p95_ratio,reference_reached,self_intersections,"
      "reference_self_intersections,flipped_triangles,flipped_before_repair\n";
  auto num = [](double v) { return std::isfinite(v) ? fmt::format("{:.2f}", v) : std::string(); };
  fmt::print("{:>8} {:>8} {:>8} {:>8} {:>8}  {:>9} {:>9} {:>6}  {:>9} {:>8}\n", a.label, "height", "weight", "waist",
             "hip", "rough p95", "reference", "ratio", "self-int", "flipped (before repair)");
  for (const auto& r : rows) {
    const PlausibilityReport& p = r.plausibility;
    const bool ref = !a.no_reference;
    csv += fmt::format("{:g},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", r.value, csv_field(r.file),
                       r.summary.converged ? 1 : 0,
                       num(p.measured.height_cm), num(p.measured.weight_kg), num(p.measured.waist_iliac_cm),
                       num(p.measured.hips_cm), num(p.roughness.p95_deg), num(p.roughness.max_deg),
                       ref ? num(p.reference.p95_deg) : "", ref ? num(p.reference.max_deg) : "",
                       ref ? num(p.p95_ratio()) : "", ref ? (p.reference_reached ? "1" : "0") : "",
                       p.self_intersections, ref ? std::to_string(p.reference_self_intersections) : "", r.flipped,
                       r.flipped_before);
    fmt::print("{:>8g} {:>8.1f} {:>8.1f} {:>8.1f} {:>8.1f}  {:>9.1f} {:>9} {:>6}  {:>9} {:>8}{}\n", r.value,
               p.measured.height_cm, p.measured.weight_kg, p.measured.waist_iliac_cm, p.measured.hips_cm,
               p.roughness.p95_deg, ref ? fmt::format("{:.1f}", p.reference.p95_deg) : "-",
               ref ? fmt::format("{:.2f}", p.p95_ratio()) : "-", p.self_intersections,
               fmt::format("{} ({})", r.flipped, r.flipped_before),
               r.summary.converged ? "" : "  (labels not all met)");
  }
  return csv;
}

// Front and side views of every body in a row.
void write_sweep_picture(const std::vector<Eigen::MatrixX3d>& bodies, const Eigen::MatrixX3i& F,
                         const std::filesystem::path& png_path) {
  Camera side;
  side.forward = Eigen::Vector3d(-1, 0, 0);
  const Image front = render_row(bodies, F, {}, 180, 440), profile = render_row(bodies, F, {}, 180, 440, side);
  Image png(front.width, 880);
  png.paste(front, 0, 0);
  png.paste(profile, 0, 440);
  png.save_png(png_path);
}

void run_sweep(SweepArgs& a) {
  std::vector<double> values;
  for (const auto& v : cli::split_commas(a.values)) values.push_back(model_cli::parse_number(v, "--values"));
  if (values.empty()) throw InputError("--values: no value given");
  StagedFolder out(a.out, a.force);
  auto model = std::make_shared<const BodyModel>(model_cli::load_model_for_cli(a.model));
  const SemanticRegression& reg = model->shape.regression;
  const LabelInfo& swept = reg.labels[reg.index(a.label)];
  std::vector<LabelCondition> fixed;
  for (auto& s : a.set) {
    auto [label, text] = model_cli::split_assignment(s, "--set");
    if (label == a.label) throw InputError("--set " + label + ": that is the swept label");
    const int i = reg.index(label);
    fixed.push_back(LabelCondition::exact(label, model_cli::check_label_range(
                                                     reg.labels[i], model_cli::parse_label_value(label, text), a.clamp)));
  }
  for (auto& k : a.keep) {
    reg.index(k);
    fixed.push_back(LabelCondition::keep_current(k));
  }
  for (double& v : values) v = model_cli::check_label_range(swept, v, a.clamp);
  if (a.bmi > 0) {
    if (a.label != "height_cm") throw InputError("--bmi needs --label height_cm");
    for (auto& c : fixed)
      if (c.label == "weight_kg") throw InputError("--bmi sets weight_kg: do not --set or --keep it too");
    reg.index("weight_kg");
  }
  Mesh start;
  if (!a.in.empty()) {
    start = read_mesh(a.in);
    model->check_topology(start.V, start.F, "'" + a.in + "'");
    check_body_size(start.V, "'" + a.in + "'");
  } else if (!a.keep.empty()) {
    throw InputError("--keep needs a start body (--in)");
  }
  MorphOptions o;
  for (auto& c : fixed)
    if (c.label == "sex" && !c.keep) o.sex = c.lo < 0.5 ? Sex::female : Sex::male;
  o.prior_weighted = a.change.empty() ? a.in.empty() : a.change == "likely";
  double years = reg.find("age_years") >= 0 ? reg.labels[reg.index("age_years")].mean : 40;
  for (auto& c : fixed)
    if (c.label == "age_years" && !c.keep) years = c.lo;
  cli::info("loading MakeHuman data from " + data_root().string() + " (roughness region and references)");
  const MakeHuman mh = MakeHuman::load();
  const ShapeMorpher morpher(model);
  const Eigen::MatrixX3i& F = model->tmpl->faces();
  std::vector<SweepRow> rows(values.size());
  std::vector<Eigen::MatrixX3d> bodies(values.size());
  cli::ProgressBar bar("sweep");
  const ProgressCallback progress = bar.callback();
  std::mutex mutex;
  std::atomic<int> done{0};
  tbb::task_arena arena(a.jobs > 0 ? a.jobs : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(0, static_cast<int>(values.size()), [&](int k) {
      std::vector<LabelCondition> cond = fixed;
      cond.push_back(LabelCondition::exact(a.label, values[k]));
      if (a.bmi > 0) cond.push_back(LabelCondition::exact("weight_kg", a.bmi * values[k] * values[k] / 1e4));
      SweepRow& r = rows[k];
      r.value = values[k];
      // morph_body: the morph and fold repair `morph` runs; measured after the repair.
      MorphedBody m = morph_body(morpher, a.in.empty() ? nullptr : &start.V, cond, o);
      bodies[k] = std::move(m.V);
      r.summary = m.summary;
      r.flipped_before = m.folds.flipped_before;
      r.flipped = flipped_triangle_count(*model, bodies[k]);
      if (a.no_reference) {
        r.plausibility.measured = measure_body(bodies[k], F, o.sex);
        r.plausibility.roughness = roughness(bodies[k], F, mh.trunk_and_limbs_region());
        r.plausibility.self_intersections = self_intersecting_triangle_pairs(bodies[k], F);
      } else {
        r.plausibility = plausibility_against_makehuman(mh, bodies[k], F, o.sex, years);
      }
      r.file = fmt::format("{}_{:g}.obj", a.label, values[k]);
      write_mesh(out / r.file, bodies[k], F);
      const int d = ++done;
      std::lock_guard<std::mutex> lock(mutex);
      report_progress(progress, static_cast<double>(d) / values.size(), r.file);
    });
  });
  bar.finish();
  write_text_file(out / "sweep.csv", sweep_table(a, rows));
  write_sweep_picture(bodies, F, out / "sweep.png");
  out.commit();
  cli::info("wrote " + a.out + "/sweep.csv, sweep.png and " + std::to_string(rows.size()) + " bodies");
}

}  // namespace

BODYMODEL_VERB(add_model_sweep_verb) {
  auto a = std::make_shared<SweepArgs>();
  auto* cmd = app.add_subcommand(
      "sweep",
      "Morph through a range of one label (a weight or height sweep) and judge every body: measured\n"
      "labels, roughness (p95 and max of the vertex-normal angle to the one-ring mean, trunk and\n"
      "limbs, core/plausibility.h) against the MakeHuman body with the nearest sliders (fitted to\n"
      "the body's height, weight, waist and hip), self-intersecting triangle pairs, flipped\n"
      "triangles (after generate's fold repair; before it in sweep.csv). Start: the model's mean body with the most likely change (as `morph` without\n"
      "--in), or --in BODY with the smallest. Writes OUT/<label>_<value>.obj, OUT/sweep.csv and\n"
      "OUT/sweep.png (front and side).");
  add_sweep_options(cmd, *a);
  cmd->callback([a] { run_sweep(*a); });
}

}  // namespace bodymodel
