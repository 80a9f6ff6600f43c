// `bodymodel skin eval SEQUENCE/ | FILES...`: Jacka et al. 2007's comparison of every skinning
// method on a mesh sequence or an unordered set of poses (docs/skinning.md; issue 26).
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <fstream>
#include <memory>
#include <set>
#include <sstream>

#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/mesh_io.h"
#include "skinning/sequence_evaluation.h"
#include "tools/console.h"
#include "tools/verb.h"
#include "tools/verbs/skinning_common.h"

namespace bodymodel::cli {
namespace {

struct EvalArgs {
  std::vector<std::string> inputs;
  std::string list, out = "report", methods = "ssd,dqs,as,mwe,psd,eigenskin,quadratic", train, test, rest;
  std::string cv = "auto", cv_rule = "min", cv_nesting = cv_nesting_name(SkinCrossValidationOptions{}.nesting);
  int train_every = 0, train_count = 0, bones = 24, max_influences = SequenceEvaluationOptions{}.max_influences, alternations = SequenceEvaluationOptions{}.alternations;
  int transform_iterations = SequenceEvaluationOptions{}.transform_iterations;
  double alternation_tolerance = SequenceEvaluationOptions{}.alternation_tolerance;
  int alternation_transform_iterations = SequenceEvaluationOptions{}.alternation_transform_iterations;
  double train_fraction = 0;
  bool leave_one_out = false, per_frame_faces = false, save_posed = false;
  double as_ridge = AnimationSpaceFitOptions{}.ridge;
  double mwe_s = MweFitOptions{}.ridge_scale;
  int mwe_components = MweFitOptions{}.components;
  double mwe_variance = MweFitOptions{}.variance_kept;
  std::string mwe_base = "ssd";
  double color_scale = 0;   // 0 = 1% of the bbox diagonal
  unsigned seed = 1;
};

void merge(DeviationStats& a, const DeviationStats& b) {
  a.count += b.count;
  a.frames += b.frames;
  a.sum_geometric += b.sum_geometric;
  a.max_geometric = std::max(a.max_geometric, b.max_geometric);
  a.sum_normal += b.sum_normal;
  a.max_normal = std::max(a.max_normal, b.max_normal);
  a.sum_vertex += b.sum_vertex;
  a.sum_vertex_sq += b.sum_vertex_sq;
  a.max_vertex = std::max(a.max_vertex, b.max_vertex);
}

// Non-blank lines of a text file, '#' comments and surrounding blanks removed.
std::vector<std::string> read_lines(const std::string& path, const std::string& what) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot read " + what);
  std::vector<std::string> out;
  std::string line;
  while (std::getline(in, line)) {
    line = line.substr(0, line.find('#'));
    line.erase(0, line.find_first_not_of(" \t\r"));
    line.erase(line.find_last_not_of(" \t\r") + 1);
    if (!line.empty()) out.push_back(line);
  }
  if (out.empty()) throw InputError(path + ": " + what + " is empty");
  return out;
}

// Names from "a,b,c" or "@file" (one name per line, '#' comments).
std::vector<std::string> names_of(const std::string& value, const char* flag) {
  if (value.empty() || value[0] != '@') return split_commas(value);
  return read_lines(value.substr(1), std::string("the name list given to ") + flag);
}

MeshSequence read_inputs(const EvalArgs& a) {
  std::vector<std::string> inputs = a.inputs;
  if (!a.list.empty())
    for (const auto& f : read_lines(a.list, "the list of mesh files")) inputs.push_back(f);
  if (inputs.empty()) throw InputError("give a folder of frames, mesh files, or --list FILE");
  if (inputs.size() == 1 && std::filesystem::is_directory(inputs[0]))
    return read_mesh_sequence(inputs[0], a.per_frame_faces);
  std::vector<std::filesystem::path> files;
  for (const auto& s : inputs) {
    if (std::filesystem::is_directory(s))
      throw InputError(s + ": a folder among several inputs (give one folder, or mesh files)");
    if (!std::filesystem::exists(s)) throw InputError(s + ": no such mesh file");
    if (!is_mesh_file_name(s)) throw InputError(s + ": not a mesh file (expected .obj, .ply or .off)");
    files.push_back(s);
  }
  return read_mesh_files(files, a.per_frame_faces);
}

// "auto", "none", "folds:K", "last:N" (N = 0: a third).
SkinCrossValidationOptions parse_cv(const std::string& s, bool future_split) {
  SkinCrossValidationOptions o;
  auto number = [&](const std::string& v) {
    try {
      size_t used = 0;
      const int n = std::stoi(v, &used);
      if (used != v.size() || n < 0) throw std::invalid_argument(v);
      return n;
    } catch (const std::exception&) {
      throw InputError("--cv: expected auto, none, folds:K or last:N, found '" + s + "'");
    }
  };
  if (s == "none") {
    o.scheme = CvScheme::none;
  } else if (s == "auto") {
    o.scheme = future_split ? CvScheme::last : CvScheme::interleaved;
  } else if (s.rfind("folds:", 0) == 0) {
    o.scheme = CvScheme::interleaved;
    o.folds = number(s.substr(6));
  } else if (s.rfind("last:", 0) == 0) {
    o.scheme = CvScheme::last;
    o.held_out = number(s.substr(5));
  } else {
    throw InputError("--cv: expected auto, none, folds:K or last:N, found '" + s + "'");
  }
  return o;
}

std::string cv_text(const SkinCrossValidationOptions& o) {
  if (o.scheme == CvScheme::none) return "none (settings as given)";
  const std::string rule = fmt::format(", rule {}, nesting {}", cv_rule_name(o.rule), cv_nesting_name(o.nesting));
  if (o.scheme == CvScheme::interleaved) return fmt::format("{}-fold interleaved over the training frames{}", o.folds, rule);
  return (o.held_out > 0 ? fmt::format("the last {} training frames held back", o.held_out)
                         : std::string("the last third of the training frames held back")) + rule;
}

void run_eval(const EvalArgs& a) {
  const MeshSequence all = read_inputs(a);
  SequenceEvaluationOptions opt;
  opt.methods.clear();
  for (const auto& m : split_commas(a.methods)) opt.methods.push_back(parse_skinning_model(m));
  if (opt.methods.empty()) throw InputError("--methods: no method given");
  opt.recovery.bones = a.bones;
  opt.recovery.seed = a.seed;
  opt.max_influences = a.max_influences;
  opt.alternations = a.alternations;
  opt.alternation_tolerance = a.alternation_tolerance;
  opt.alternation_transform_iterations = a.alternation_transform_iterations;
  opt.transform_iterations = a.transform_iterations;
  opt.fit.animation_space.ridge = a.as_ridge;
  opt.fit.mwe.ridge_scale = a.mwe_s;
  opt.fit.mwe.components = a.mwe_components;
  opt.fit.mwe.variance_kept = a.mwe_variance;
  if (a.mwe_base == "ssd") opt.fit.mwe.base = MweBase::lbs;
  else if (a.mwe_base == "as") opt.fit.mwe.base = MweBase::animation_space;
  else if (a.mwe_base == "rigid") opt.fit.mwe.base = MweBase::rigid;
  else if (a.mwe_base == "none") opt.fit.mwe.base = MweBase::none;
  else throw InputError("--mwe-base: expected ssd, as, rigid or none, found '" + a.mwe_base + "'");
  const std::string source = a.inputs.size() == 1 && a.list.empty() ? a.inputs[0]
                             : fmt::format("{} mesh files", all.names.size());
  auto index_in = [&](const MeshSequence& s, const std::string& name, const char* flag) {
    for (size_t f = 0; f < s.names.size(); ++f)
      if (s.names[f] == name) return static_cast<int>(f);
    throw InputError(std::string(flag) + " names frame '" + name + "', which is not among the " +
                     std::to_string(s.names.size()) + " frames of " + source +
                     " (names are file names without extension)");
  };
  // An explicit test list keeps only the training and test frames, in input order.
  MeshSequence seq;
  if (!a.test.empty()) {
    if (a.train.empty()) throw InputError("--test needs --train (the explicit split names both sides)");
    std::set<int> keep;
    for (const auto& n : names_of(a.train, "--train")) keep.insert(index_in(all, n, "--train"));
    std::set<int> test;
    for (const auto& n : names_of(a.test, "--test")) {
      const int f = index_in(all, n, "--test");
      if (keep.count(f)) throw InputError("frame '" + n + "' is in both --train and --test");
      test.insert(f);
    }
    keep.insert(test.begin(), test.end());
    for (int f : keep) {
      seq.names.push_back(all.names[static_cast<size_t>(f)]);
      seq.frames.push_back(all.frames[static_cast<size_t>(f)]);
      if (!all.frame_faces.empty()) seq.frame_faces.push_back(all.frame_faces[static_cast<size_t>(f)]);
    }
    seq.F = all.frame_faces.empty() ? all.F : seq.frame_faces[0];
  } else {
    seq = all;
  }
  const int nf = static_cast<int>(seq.frames.size());

  // Folds: one, or leave-one-out.
  std::vector<std::vector<int>> folds;
  std::string protocol;
  int rest = -1;
  if (!a.rest.empty()) rest = index_in(seq, a.rest, "--rest");
  if (a.leave_one_out) {
    if (rest < 0) rest = 0;
    for (int f = 0; f < nf; ++f) {
      if (f == rest) continue;   // the rest frame is always a training frame
      std::vector<int> t;
      for (int g = 0; g < nf; ++g)
        if (g != f) t.push_back(g);
      folds.push_back(t);
    }
    protocol = fmt::format("leave-one-out over {} frames (rest frame {} always trained)", nf,
                           seq.names[static_cast<size_t>(rest)]);
  } else {
    std::vector<int> t;
    if (!a.train.empty()) {
      for (const auto& n : names_of(a.train, "--train")) t.push_back(index_in(seq, n, "--train"));
      protocol = a.test.empty() ? fmt::format("{} training frames listed with --train, the other {} unseen", t.size(),
                                              nf - static_cast<int>(std::set<int>(t.begin(), t.end()).size()))
                                : fmt::format("explicit split: {} training frames (--train), {} unseen (--test)",
                                              t.size(), nf - static_cast<int>(t.size()));
    } else if (a.train_fraction > 0) {
      if (!(a.train_fraction < 1)) throw InputError("--train-fraction must be in (0, 1)");
      const int k = std::max(1, static_cast<int>(std::lround(a.train_fraction * nf)));
      for (int f = 0; f < k; ++f) t.push_back(f);
      protocol = fmt::format("the first {} of {} frames trained ({:g} %), the rest unseen", k, nf, 100 * a.train_fraction);
    } else if (a.train_every > 0) {
      for (int f = 0; f < nf; f += a.train_every) t.push_back(f);
      protocol = fmt::format("every {}th frame trained", a.train_every);
    } else {
      // Default: 10 frames, but always leave one unseen on short sequences.
      const int k = a.train_count > 0 ? a.train_count : std::max(1, std::min(10, nf - 1));
      t = evenly_spaced_frames(nf, k);
      protocol = fmt::format("{} evenly spaced training frames", t.size());
    }
    // Training on every frame leaves no unseen split to report (--train-count 1000 did so silently).
    if (static_cast<int>(std::set<int>(t.begin(), t.end()).size()) >= nf)
      throw InputError(fmt::format("skin eval: the training frames ({}) are all {} frames of the sequence, leaving "
                                   "no unseen frame to measure (train on at most {})",
                                   protocol, nf, nf - 1));
    if (rest < 0) rest = *std::min_element(t.begin(), t.end());
    folds.push_back(t);
  }
  opt.rest_frame = rest;
  opt.frame_faces = seq.frame_faces;
  // Cross-validation: "auto" holds back the last training frames when every unseen frame comes
  // after every training frame (a forecast), else interleaved folds.
  bool future = !a.leave_one_out;
  if (future) {
    const int last_train = *std::max_element(folds[0].begin(), folds[0].end());
    const std::set<int> tset(folds[0].begin(), folds[0].end());
    bool any_unseen = false;
    for (int f = 0; f < nf; ++f)
      if (!tset.count(f)) {
        any_unseen = true;
        if (f < last_train) future = false;
      }
    future = future && any_unseen && a.test.empty();
  }
  opt.cv = parse_cv(a.cv, future);
  opt.cv.rule = parse_cv_rule(a.cv_rule);
  opt.cv.nesting = parse_cv_nesting(a.cv_nesting);

  for (const auto& fold : folds) check_evaluation_request(nf, fold, opt);
  ensure_directory(a.out);
  if (a.save_posed) {
    if (a.leave_one_out) throw InputError("--save-posed needs a single split (not --leave-one-out)");
    opt.on_posed = [&](SkinningModel m, int f, const Eigen::MatrixX3d& X) {
      const auto dir = std::filesystem::path(a.out) / "posed" / skinning_model_name(m);
      ensure_directory(dir);
      write_mesh(dir / (seq.names[static_cast<size_t>(f)] + ".obj"), X,
                 seq.frame_faces.empty() ? seq.F : seq.frame_faces[static_cast<size_t>(f)]);
    };
  }
  ProgressBar bar("skin eval");
  const size_t M = opt.methods.size();
  std::vector<DeviationStats> train(M), unseen(M);
  std::vector<Eigen::VectorXd> per_vertex(M, Eigen::VectorXd::Zero(seq.frames[0].rows()));
  std::vector<std::vector<double>> frame_err(M, std::vector<double>(static_cast<size_t>(nf), 0.0));
  std::vector<std::string> frame_split(static_cast<size_t>(nf), "train");
  std::vector<double> fit_cpu(M, 0.0);
  SequenceEvaluation last;
  double seconds = 0, prep_cpu = 0, cv_setup_cpu = 0;
  std::string cv_csv =
      "fold,method,setting,held_out_mean_error,standard_error,paired_standard_error,held_out_examples,chosen,chosen_by\n";
  for (size_t fold = 0; fold < folds.size(); ++fold) {
    auto cb = bar.callback();
    ProgressCallback sub = [&](double f, std::string_view w) { return cb((fold + f) / folds.size(), w); };
    last = evaluate_skinning_sequence(seq.frames, seq.F, folds[fold], opt, {}, sub);
    seconds += last.seconds;
    prep_cpu += last.prepare_cpu_seconds;
    cv_setup_cpu += last.cv_setup_cpu_seconds;
    for (const auto& row : last.rows) {
      size_t m = 0;
      while (opt.methods[m] != row.method) ++m;
      merge(row.split == "train" ? train[m] : unseen[m], row.stats);
    }
    for (size_t m = 0; m < M; ++m) {
      fit_cpu[m] += last.fits[m].cpu_seconds;
      // chosen_by: the rules that would keep this candidate (the choice of the others can be read
      // off without a rerun; only the rule in force shapes the fitted models, though).
      std::vector<CvCandidate> cands = last.fits[m].cv.candidates;
      std::vector<std::string> by(cands.size());
      if (!cands.empty())
        for (CvRule r : {CvRule::minimum, CvRule::one_se, CvRule::one_se_unpaired}) {
          std::string& b = by[select_candidate(cands, r)];
          b += (b.empty() ? "" : " ") + cv_rule_name(r);
        }
      for (size_t k = 0; k < cands.size(); ++k) {
        const CvCandidate& c = cands[k];
        cv_csv += fmt::format("{},{},{},{:.8g},{:.4g},{:.4g},{},{},{}\n", fold, skinning_model_name(opt.methods[m]),
                              csv_field(c.setting), c.error, c.standard_error, c.paired_standard_error,
                              c.example_errors.size(),
                              c.setting == last.fits[m].cv.chosen_setting ? 1 : 0, by[k]);
      }
    }
    std::set<int> tset(folds[fold].begin(), folds[fold].end());
    for (size_t m = 0; m < M; ++m) {
      per_vertex[m] += last.mean_unseen_geometric[m] / double(folds.size());
      for (int f = 0; f < nf; ++f)
        if (!tset.count(f) || folds.size() == 1)
          frame_err[m][static_cast<size_t>(f)] = last.frame_mean_geometric[m][static_cast<size_t>(f)];
    }
    for (int f = 0; f < nf; ++f)
      if (!tset.count(f)) frame_split[static_cast<size_t>(f)] = "unseen";
  }
  bar.finish();
  const double d = last.diagonal;
  std::string csv =
      "method,split,mean_geometric,max_geometric,mean_normal_deg,max_normal_deg,rms_vertex,e_rms,frames,fit_cpu_s\n";
  std::string md = fmt::format(
      "# Skinning comparison: {}\n\nProtocol (Jacka et al. 2007): {}; bones {} {}; ≤{} influences per "
      "vertex; rest frame {}; regularisation by cross-validation on the training frames only: {}.\n"
      "Geometric deviation = distance of each skinned vertex to the closest point of the reference *surface*; "
      "normal deviation = angle between area-weighted vertex normals; vertex RMS and E_RMS (Kavan et al. 2010: "
      "1000·‖X − Y‖_F / (√(3·#V·#frames)·d)) against the same vertex. Units: the sequence's own (d = bounding-box "
      "diagonal of the first frame {}: {:.4f}). Means over all vertices of all frames of the split. Fit CPU = "
      "seconds of CPU (all threads) for the method's cross-validation and final fit, over the SSD base "
      "(bones + SSD: {:.1f} s CPU) and the cross-validation folds' own SSD bases (and bones, nesting full: "
      "{:.1f} s CPU).\n\n"
      "| method | split | frames | mean geometric | max geometric | mean geom. % diag | mean normal (°) | max normal (°) | vertex RMS | E_RMS | fit CPU (s) |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|\n",
      source, protocol, a.bones, "(recovered: k-means on triangle rotation sequences + EM refinement + SSD alternation)",
      a.max_influences, seq.names[static_cast<size_t>(opt.rest_frame)], cv_text(opt.cv), seq.names[0], d, prep_cpu,
      cv_setup_cpu);
  for (size_t m = 0; m < M; ++m)
    for (int s = 0; s < 2; ++s) {
      const DeviationStats& st = s == 0 ? train[m] : unseen[m];
      if (st.count == 0) continue;
      const std::string name = skinning_model_name(opt.methods[m]), split = s == 0 ? "train" : "unseen";
      csv += fmt::format("{},{},{:.8g},{:.8g},{:.6g},{:.6g},{:.8g},{:.6g},{},{:.3f}\n", name, split, st.mean_geometric(),
                         st.max_geometric, st.mean_normal_deg(), st.max_normal, st.rms_vertex(), st.e_rms(d), st.frames,
                         fit_cpu[m]);
      md += fmt::format("| {} | {} | {} | {:.6f} | {:.5f} | {:.4f} | {:.3f} | {:.1f} | {:.6f} | {:.4f} | {:.1f} |\n", name,
                        split, st.frames, st.mean_geometric(), st.max_geometric, 100 * st.mean_geometric() / d,
                        st.mean_normal_deg(), st.max_normal, st.rms_vertex(), st.e_rms(d), fit_cpu[m]);
    }
  // All frames together, as Jacka's Table 1 reports (mean over every pose of the data set).
  md += "\nAll frames together (Jacka et al. Table 1 reports means over every pose of the data set):\n\n"
        "| method | mean geometric | max geometric | mean normal (°) | max normal (°) |\n|---|---|---|---|---|\n";
  for (size_t m = 0; m < M; ++m) {
    DeviationStats both = train[m];
    merge(both, unseen[m]);
    md += fmt::format("| {} | {:.6f} | {:.5f} | {:.3f} | {:.1f} |\n", skinning_model_name(opt.methods[m]),
                      both.mean_geometric(), both.max_geometric, both.mean_normal_deg(), both.max_normal);
  }
  md += fmt::format("\nFits (last fold): {}; {}. CPU: bone recovery {:.2f} s, SSD and alternation {:.2f} s, "
                    "unseen-frame bone maps {:.2f} s. Alternation: {} round(s), training residual RMS {}.\n",
                    last.recovery.brief(), last.lbs_summary.brief(), last.recovery_cpu_seconds,
                    last.prepare_cpu_seconds - last.recovery_cpu_seconds, last.unseen_cpu_seconds,
                    last.alternation_rms.empty() ? 0 : last.alternation_rms.size() - 1,
                    fmt::join(last.alternation_rms, " → "));
  for (const auto& f : last.fits) {
    md += "- " + f.brief;
    if (!f.cv.candidates.empty()) md += "; cross-validation: " + f.cv.brief();
    md += "\n";
  }
  md += fmt::format("\nTotal {:.1f} s.\n", seconds);
  std::string frames_csv = "frame,split";
  for (auto m : opt.methods) frames_csv += ",mean_geometric_" + skinning_model_name(m);
  frames_csv += "\n";
  for (int f = 0; f < nf; ++f) {
    frames_csv += csv_field(seq.names[static_cast<size_t>(f)]) + "," + frame_split[static_cast<size_t>(f)];
    for (size_t m = 0; m < M; ++m) frames_csv += fmt::format(",{:.8g}", frame_err[m][static_cast<size_t>(f)]);
    frames_csv += "\n";
  }
  const std::filesystem::path out(a.out);
  write_text_file(out / "skinning.csv", csv);
  write_text_file(out / "skinning.md", md);
  write_text_file(out / "skinning_frames.csv", frames_csv);
  write_text_file(out / "skinning_cv.csv", cv_csv);
  const double scale = a.color_scale > 0 ? a.color_scale : 0.01 * d;
  for (size_t m = 0; m < M; ++m)
    write_mesh(out / ("unseen_error_" + skinning_model_name(opt.methods[m]) + ".ply"),
               seq.frames[static_cast<size_t>(opt.rest_frame)],
               seq.frame_faces.empty() ? seq.F : seq.frame_faces[static_cast<size_t>(opt.rest_frame)],
               error_colors(per_vertex[m], scale));
  std::printf("%s", md.c_str());
  info(fmt::format("wrote {}/skinning.csv, skinning.md, skinning_frames.csv, skinning_cv.csv and "
                   "unseen_error_<method>.ply (mean unseen geometric error per vertex on the rest mesh, blue 0 → red ≥ {:.5g})",
                   a.out, scale));
}

}  // namespace

BODYMODEL_VERB(add_skin_eval_verb) {
  CLI::App* skin = skin_group(app);
  auto* cmd = skin->add_subcommand(
      "eval",
      "Compare skinning methods on a mesh sequence or a set of poses (Jacka et al. 2007 protocol):\n"
      "recover bones from the training frames, fit every method on them (regularisation chosen by\n"
      "cross-validation on the training frames only), measure training and unseen frames.\n"
      "Inputs: one folder of .obj/.ply/.off frames (sorted by name), or mesh files, or --list FILE;\n"
      "frames are named by file name without extension. Examples:\n"
      "  bodymodel skin eval horse-gallop/ --train-count 10 --out r/\n"
      "  bodymodel skin eval vlasic-jumping/ --train-fraction 0.6 --out r/    # forecast: CV holds back the last third\n"
      "  bodymodel skin eval scape/ --per-frame-faces --train @train.txt --test @test.txt --out r/");
  auto a = std::make_shared<EvalArgs>();
  cmd->add_option("inputs", a->inputs, "A folder of frames sharing one connectivity, or mesh files");
  cmd->add_option("--list", a->list, "Text file naming mesh files, one per line (added to the inputs)");
  cmd->add_option("--out", a->out, "Report folder (skinning.csv, skinning.md, skinning_frames.csv, skinning_cv.csv, PLYs)")
      ->capture_default_str();
  cmd->add_option("--methods", a->methods, "Comma-separated methods: ssd, dqs, as, mwe, psd, eigenskin, quadratic")
      ->capture_default_str();
  cmd->add_option("--train-every", a->train_every, "Train on every K-th frame (frame 1, 1+K, ...)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--train-count", a->train_count, "Train on N evenly spaced frames (default 10, at most all frames but one)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--train-fraction", a->train_fraction, "Train on the first fraction of the frames (0.6 = first 60 %)");
  cmd->add_option("--train", a->train, "Training frame names, comma-separated or @file (one per line)");
  cmd->add_option("--test", a->test, "Unseen frame names (with --train): every other frame is ignored");
  cmd->add_flag("--leave-one-out", a->leave_one_out, "Hold out each frame in turn (for sequences of few poses)");
  cmd->add_flag("--per-frame-faces", a->per_frame_faces,
                "Accept frames whose vertices correspond but whose triangles differ (SCAPE): each frame's own faces "
                "give its surface and normals, the rest frame's the bone recovery");
  cmd->add_option("--rest", a->rest, "Frame used as the rest pose, a training frame (default: the first training frame)");
  cmd->add_option("--bones", a->bones, "Bones to recover (rigid sections)")->capture_default_str();
  cmd->add_option("--max-influences", a->max_influences, "Influence bones per vertex")->capture_default_str();
  cmd->add_option("--alternations", a->alternations, "SSD weight / bone transform alternation rounds (at most)")->capture_default_str();
  cmd->add_option("--alternation-transform-iterations", a->alternation_transform_iterations,
                  "Bone-by-bone passes of the transform fit inside each alternation round (0 = --transform-iterations)")
      ->capture_default_str();
  cmd->add_option("--alternation-tolerance", a->alternation_tolerance,
                  "Stop alternating once a round lowers the training residual RMS by less than this fraction (0 = never)")
      ->capture_default_str();
  cmd->add_option("--transform-iterations", a->transform_iterations,
                  "Bone-by-bone passes of each fixed-weight bone transform fit (training alternation and unseen frames)")
      ->capture_default_str();
  cmd->add_option("--cv", a->cv,
                  "Cross-validation on the training frames: auto (last third held back when the unseen frames all follow "
                  "the training frames, else 5 interleaved folds), none, folds:K, last:N")
      ->capture_default_str();
  cmd->add_option("--cv-rule", a->cv_rule,
                  "Which cross-validated setting is kept: one-se (the most regularised within one paired standard "
                  "error of the smallest held-out mean), min (the smallest), one-se-unpaired")
      ->capture_default_str();
  cmd->add_option("--cv-nesting", a->cv_nesting,
                  "What each cross-validation fold refits on its training part: weights (the SSD base; held-out frames "
                  "keep the bone maps fitted with all training frames) or full (bone recovery and SSD alternation too, "
                  "held-out bone maps fitted like unseen frames; about one more bones + SSD fit per fold)")
      ->capture_default_str();
  cmd->add_option("--as-ridge", a->as_ridge, "Animation Space ridge λ (relative; used as given with --cv none)");
  cmd->add_option("--mwe-s", a->mwe_s, "MWE ridge scale s, relative to the diagonal (λ_h = s·d⁴/σ²(c_h); with --cv none)");
  cmd->add_option("--mwe-components", a->mwe_components, "MWE principal components kept (0 = by variance)");
  cmd->add_option("--mwe-variance", a->mwe_variance, "MWE variance fraction kept when components = 0");
  cmd->add_option("--mwe-base", a->mwe_base, "MWE underlying system with --cv none: ssd, as, rigid or none");
  cmd->add_flag("--save-posed", a->save_posed,
                "Also write every posed frame of every method to OUT/posed/<method>/<frame>.obj (for an outside check "
                "of the errors, e.g. the numpy script in docs/skinning.md)");
  cmd->add_option("--color-scale", a->color_scale, "Error mapped to red in the PLYs (default 1% of the diagonal)");
  cmd->add_option("--seed", a->seed, "Seed of the bone clustering");
  cmd->callback([a] { run_eval(*a); });
}

}  // namespace bodymodel::cli
