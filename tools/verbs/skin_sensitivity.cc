// `bodymodel skin sensitivity SEQUENCE/`: mean unseen-frame error over a grid of MWE's two
// parameters (principal components kept, ridge scale s) and Animation Space's ridge (Jacka et al.
// 2007 §4.3, Fig. 3), reusing one bone recovery and SSD fit.
#include <fmt/format.h>

#define STB_IMAGE_WRITE_STATIC   // private copy: no clash with other verbs using stb
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>

#include <memory>
#include <sstream>

#include "core/io/atomic_write.h"
#include "skinning/sequence_evaluation.h"
#include "tools/console.h"
#include "tools/verb.h"
#include "tools/verbs/skin_common.h"

namespace bodymodel::cli {
namespace {

struct SensitivityArgs {
  std::string sequence, out = "report";
  int train_count = 10, bones = 24, max_influences = 4;
  std::string components = "0,1,2,3,4,6,8,12,16";
  std::string scales = "0,1e-10,1e-9,2e-9,1e-8,1e-7,1e-6,1e-5,1e-4";
  std::string ridges = "0,1e-5,1e-4,1e-3,3e-3,1e-2,3e-2,0.1,0.3";
};

template <typename T>
std::vector<T> parse_list(const std::string& s, const char* what) {
  std::vector<T> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      out.push_back(static_cast<T>(std::stod(item)));
    } catch (...) {
      throw InputError(std::string(what) + ": expected a comma-separated list of numbers, found '" + item + "'");
    }
  }
  if (out.empty()) throw InputError(std::string(what) + ": empty list");
  return out;
}

void write_heatmap_png(const std::filesystem::path& path, const Eigen::MatrixXd& E) {
  // One 24×24 cell per grid point, colour = log error (blue low → red high).
  const int cell = 24, w = static_cast<int>(E.cols()) * cell, h = static_cast<int>(E.rows()) * cell;
  const double lo = std::log(E.minCoeff()), hi = std::log(E.maxCoeff());
  std::vector<unsigned char> px(static_cast<size_t>(w * h * 3));
  for (int r = 0; r < E.rows(); ++r)
    for (int c = 0; c < E.cols(); ++c) {
      const double t = hi > lo ? (std::log(E(r, c)) - lo) / (hi - lo) : 0.0;
      const Eigen::Vector3d col = t < 0.5 ? Eigen::Vector3d(0, 2 * t, 1 - 2 * t) : Eigen::Vector3d(2 * t - 1, 2 - 2 * t, 0);
      for (int y = r * cell; y < (r + 1) * cell; ++y)
        for (int x = c * cell; x < (c + 1) * cell; ++x)
          for (int k = 0; k < 3; ++k)
            px[static_cast<size_t>((y * w + x) * 3 + k)] =
                static_cast<unsigned char>((x % cell == 0 || y % cell == 0) ? 255 : 255 * col(k));
    }
  int len = 0;
  unsigned char* png = stbi_write_png_to_mem(px.data(), w * 3, w, h, 3, &len);
  if (!png) throw InputError(path.string() + ": could not encode the PNG");
  const std::string bytes(reinterpret_cast<char*>(png), static_cast<size_t>(len));
  STBIW_FREE(png);
  write_atomically(path, [&](std::ostream& o) { o << bytes; });
}

void run_sensitivity(const SensitivityArgs& a) {
  const MeshSequence seq = read_mesh_sequence(a.sequence);
  const auto comps = parse_list<int>(a.components, "--components");
  const auto scales = parse_list<double>(a.scales, "--scales");
  const auto ridges = parse_list<double>(a.ridges, "--ridges");
  SequenceEvaluationOptions opt;
  opt.recovery.bones = a.bones;
  opt.max_influences = a.max_influences;
  const auto train = evenly_spaced_frames(static_cast<int>(seq.frames.size()), a.train_count);
  ProgressBar bar("skin sensitivity");
  auto cb = bar.callback();
  const PreparedSequence prep = prepare_skinning_sequence(seq.frames, seq.F, train, opt, {},
      [&](double f, std::string_view w) { return cb(0.1 * f, w); });
  std::vector<std::unique_ptr<ReferenceSurface>> trees;
  std::vector<const ReferenceSurface*> surfaces;
  for (const auto& fr : seq.frames) {
    trees.push_back(std::make_unique<ReferenceSurface>(fr, seq.F));
    surfaces.push_back(trees.back().get());
  }
  std::string csv = "method,components,ridge,mean_unseen_geometric,mean_train_geometric,mean_unseen_normal_deg\n";
  const RigFrameStats base = evaluate_rig_on_frames(prep.lbs, prep, seq.frames, seq.F, surfaces);
  csv += fmt::format("ssd,,,{:.8g},{:.8g},{:.6g}\n", base.unseen.mean_geometric(), base.train.mean_geometric(),
                     base.unseen.mean_normal_deg());
  const double total = double(comps.size() * scales.size() + ridges.size());
  double done = 0;
  Eigen::MatrixXd grid(comps.size(), scales.size());
  double best = std::numeric_limits<double>::infinity();
  std::string best_mwe;
  for (size_t i = 0; i < comps.size(); ++i)
    for (size_t j = 0; j < scales.size(); ++j) {
      cb(0.1 + 0.9 * done++ / total, "MWE grid");
      MweFitOptions o;
      o.components = comps[i];
      o.ridge_scale = scales[j];
      const SkinningRig rig = fit_mwe(prep.examples, &prep.lbs, o);
      const RigFrameStats st = evaluate_rig_on_frames(rig, prep, seq.frames, seq.F, surfaces);
      grid(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = st.unseen.mean_geometric();
      csv += fmt::format("mwe,{},{:g},{:.8g},{:.8g},{:.6g}\n", comps[i], scales[j], st.unseen.mean_geometric(),
                         st.train.mean_geometric(), st.unseen.mean_normal_deg());
      if (st.unseen.mean_geometric() < best) {
        best = st.unseen.mean_geometric();
        best_mwe = fmt::format("components {} (0 = 99.9% variance), s {:g}: {:.6f}", comps[i], scales[j], best);
      }
    }
  double best_as = std::numeric_limits<double>::infinity();
  std::string best_as_text;
  for (double r : ridges) {
    cb(0.1 + 0.9 * done++ / total, "AS ridges");
    AnimationSpaceFitOptions o;
    o.ridge = r;
    const SkinningRig rig = fit_animation_space(prep.examples, &prep.lbs, o);
    const RigFrameStats st = evaluate_rig_on_frames(rig, prep, seq.frames, seq.F, surfaces);
    csv += fmt::format("as,,{:g},{:.8g},{:.8g},{:.6g}\n", r, st.unseen.mean_geometric(), st.train.mean_geometric(),
                       st.unseen.mean_normal_deg());
    if (st.unseen.mean_geometric() < best_as) {
      best_as = st.unseen.mean_geometric();
      best_as_text = fmt::format("ridge {:g}: {:.6f}", r, best_as);
    }
  }
  bar.finish();
  ensure_directory(a.out);
  const std::filesystem::path out(a.out);
  write_text_file(out / "sensitivity.csv", csv);
  write_heatmap_png(out / "sensitivity_mwe.png", grid);
  std::printf("SSD unseen mean geometric %.6f\nbest MWE %s\nbest AS %s\n", base.unseen.mean_geometric(),
              best_mwe.c_str(), best_as_text.c_str());
  info(fmt::format("wrote {}/sensitivity.csv and sensitivity_mwe.png (rows: components {}, columns: s {}; "
                   "colour: log mean unseen geometric error, blue low → red high)",
                   a.out, a.components, a.scales));
}

}  // namespace

BODYMODEL_VERB(add_skin_sensitivity_verb) {
  CLI::App* skin = skin_group(app);
  auto* cmd = skin->add_subcommand("sensitivity", "Mean unseen-frame error over a grid of MWE's (components, s) "
                                                  "and Animation Space's ridge (Jacka et al. Fig. 3)");
  auto a = std::make_shared<SensitivityArgs>();
  cmd->add_option("sequence", a->sequence, "Folder of .obj/.ply frames sharing one connectivity")->required();
  cmd->add_option("--out", a->out, "Output folder (sensitivity.csv, sensitivity_mwe.png)");
  cmd->add_option("--train-count", a->train_count, "Evenly spaced training frames");
  cmd->add_option("--bones", a->bones, "Bones to recover");
  cmd->add_option("--max-influences", a->max_influences, "Influence bones per vertex");
  cmd->add_option("--components", a->components, "MWE components kept (comma list; 0 = 99.9% variance)");
  cmd->add_option("--scales", a->scales, "MWE ridge scales s, relative (s · d⁴ is used; comma list)");
  cmd->add_option("--ridges", a->ridges, "Animation Space ridges (comma list)");
  cmd->callback([a] { run_sensitivity(*a); });
}

}  // namespace bodymodel::cli
