// bodymodel generate model.npz --count 200 --where sex=female --where weight_kg=65
//   --where height_cm=160..180 --seed 7 --out crowd/
#include <fmt/format.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <mutex>

#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "model/morph.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

struct GenerateArgs {
  std::string model, out, format = "obj";
  std::vector<std::string> where;
  int count = 10;
  uint64_t seed = 1;
  double spread = 1.0;
  bool clamp = false, no_girths = false;
  int diversity_sample = 40;
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

}  // namespace

BODYMODEL_VERB(add_model_generate_verb) {
  auto a = std::make_shared<GenerateArgs>();
  auto* cmd = app.add_subcommand(
      "generate",
      "Generate random bodies from the shape-only model (§5.2): coefficients ~ N(0, eigenvalues)\n"
      "(or the chosen sex's subjects), then the --where conditions are enforced as MEASURED on\n"
      "each output (model/morph.h). Writes OUT/body_NNN.obj and OUT/labels.csv with the measured\n"
      "labels of every body.");
  cmd->add_option("model", a->model, "Model (.npz from `bodymodel build`)")->required();
  cmd->add_option("--count", a->count, "Number of bodies")->capture_default_str()->check(CLI::Range(1, 100000));
  cmd->add_option("--where", a->where, "LABEL=VALUE or LABEL=LO..HI, repeatable (sex=female|male)");
  cmd->add_option("--seed", a->seed, "Random seed (the crowd is a function of it)")->capture_default_str();
  cmd->add_option("--spread", a->spread, "Scale of the random coefficients (1 = the data's spread)")
      ->capture_default_str();
  cmd->add_option("--format", a->format, "obj or ply")->check(CLI::IsMember({"obj", "ply"}))->capture_default_str();
  cmd->add_flag("--no-girths", a->no_girths,
                "labels.csv without the girths and body fat (height, volume, weight only): about a third "
                "faster");
  cmd->add_flag("--clamp", a->clamp, "Clamp values far outside the data to the data's range");
  cmd->add_option("--out", a->out, "Output folder")->required();
  cmd->callback([a] {
    auto model = std::make_shared<const BodyModel>(model_cli::load_model_for_cli(a->model));
    const SemanticRegression& reg = model->shape.regression;
    std::vector<LabelCondition> cond;
    for (auto& w : a->where) cond.push_back(parse_where(reg, w, a->clamp));
    ensure_directory(a->out);
    GenerateOptions go;
    go.spread = a->spread;
    go.measure_girths = !a->no_girths;
    Sex sex = Sex::unknown;
    for (auto& c : cond)
      if (c.label == "sex") sex = c.lo < 0.5 ? Sex::female : Sex::male;
    const int n = a->count;
    std::vector<GeneratedBody> bodies(n);
    std::vector<int> flipped(n, 0);
    tbb::enumerable_thread_specific<std::unique_ptr<ShapeMorpher>> morphers;
    cli::ProgressBar bar("generate");
    std::atomic<int> done{0};
    std::mutex mtx;
    auto t0 = std::chrono::steady_clock::now();
    tbb::parallel_for(0, n, [&](int i) {
      auto& m = morphers.local();
      if (!m) m = std::make_unique<ShapeMorpher>(model);
      GeneratedBody g = generate_body(*m, cond, a->seed * 1000003ull + static_cast<uint64_t>(i), go);
      flipped[i] = flipped_triangle_count(*model, g.V);
      write_mesh(std::filesystem::path(a->out) / fmt::format("body_{:03d}.{}", i, a->format), g.V,
                 model->tmpl->faces());
      g.encoding.resize(0);
      bodies[i] = std::move(g);
      int d = ++done;
      std::lock_guard<std::mutex> lock(mtx);
      bar.update(double(d) / n, fmt::format("body {}", i));
    });
    double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    bar.finish(fmt::format("{} bodies in {:.1f} s ({:.1f}/s)", n, secs, n / secs));
    std::string csv = "body,file,sex,height_cm,weight_kg,volume_l,waist_cm,hips_cm,chest_cm,neck_cm,body_fat_pct,"
                      "constraints_met,iterations,attempts,flipped_triangles\n";
    int met = 0, total_flipped = 0;
    for (int i = 0; i < n; ++i) {
      const auto& g = bodies[i];
      const auto& m = g.measured;
      met += g.satisfied ? 1 : 0;
      total_flipped += flipped[i];
      auto num = [](double v) { return std::isfinite(v) ? fmt::format("{:.2f}", v) : std::string(); };
      csv += fmt::format("{},body_{:03d}.{},{},{:.2f},{:.2f},{:.2f},{},{},{},{},{},{},{},{},{}\n", i, i,
                         a->format, sex == Sex::female ? "female" : sex == Sex::male ? "male" : "",
                         m.height_cm, m.weight_kg, m.volume_l, num(m.waist_cm), num(m.hips_cm), num(m.chest_cm),
                         num(m.neck_cm), num(m.body_fat_pct),
                         g.satisfied ? 1 : 0, g.summary.iterations, g.attempts, flipped[i]);
    }
    write_text_file(std::filesystem::path(a->out) / "labels.csv", csv);
    // Diversity: mean pairwise RMS vertex distance (after rigid fit) of a sample of the crowd,
    // against that of the model's training subjects (decoded from their coefficients).
    ShapeMorpher dm(model);
    const int k = std::min(n, a->diversity_sample);
    double gsum = 0;
    int gp = 0;
    for (int i = 0; i < k; ++i)
      for (int j = i + 1; j < k; ++j, ++gp) gsum += rms_vertex_distance(bodies[i].V, bodies[j].V);
    std::vector<Eigen::MatrixX3d> subj;
    const auto& C = model->shape.pca.coefficients;
    std::vector<int> same_sex;
    int sex_label = reg.find("sex");
    for (int i = 0; i < C.rows(); ++i)
      if (sex == Sex::unknown || sex_label < 0 ||
          std::abs(model->shape.labels(i, sex_label) - (sex == Sex::male ? 1.0 : 0.0)) < 0.5)
        same_sex.push_back(i);
    for (int i : same_sex)
      if (static_cast<int>(subj.size()) < a->diversity_sample)
        subj.push_back(dm.decode(model->shape.pca.reconstruct(C.row(i).transpose())));
    double ssum = 0;
    int sp = 0;
    for (size_t i = 0; i < subj.size(); ++i)
      for (size_t j = i + 1; j < subj.size(); ++j, ++sp) ssum += rms_vertex_distance(subj[i], subj[j]);
    fmt::print("bodies                 {}\n", n);
    fmt::print("constraints met        {} of {} (as measured on each output)\n", met, n);
    fmt::print("flipped triangles      {} in total ({:.4f}% of all triangles)\n", total_flipped,
               100.0 * total_flipped / (double(n) * model->tmpl->triangle_count()));
    fmt::print("diversity              mean pairwise RMS vertex distance {:.1f} mm (first {} bodies)\n",
               gp ? gsum / gp : 0.0, k);
    fmt::print("                       vs {:.1f} mm between the model's {} training subjects{}\n",
               sp ? ssum / sp : 0.0, subj.size(), sex == Sex::unknown ? "" : " of that sex");
    fmt::print("speed                  {:.1f} bodies/s including writing meshes\n", n / secs);
    if (met < n) cli::warn(fmt::format("{} bodies did not meet every condition (see labels.csv)", n - met));
    cli::info("wrote " + a->out + "/labels.csv");
  });
}

}  // namespace bodymodel
