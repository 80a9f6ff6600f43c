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
#include "skinning/method_comparison.h"
#include "tools/console.h"
#include "tools/verb.h"
#include "tools/verbs/skin_common.h"

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

SequenceEvaluationOptions evaluation_options(const EvalArgs& a) {
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
  return opt;
}

// The frames named by --train/--test (an explicit test list keeps only the two sides, in input
// order) and the split request of the other options.
struct SelectedFrames {
  MeshSequence seq;
  FrameSplitRequest request;
};

SelectedFrames select_frames(const EvalArgs& a, const MeshSequence& all, const std::string& source) {
  auto index_in = [&](const MeshSequence& s, const std::string& name, const char* flag) {
    for (size_t f = 0; f < s.names.size(); ++f)
      if (s.names[f] == name) return static_cast<int>(f);
    throw InputError(std::string(flag) + " names frame '" + name + "', which is not among the " +
                     std::to_string(s.names.size()) + " frames of " + source +
                     " (names are file names without extension)");
  };
  SelectedFrames out;
  MeshSequence& seq = out.seq;
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
  FrameSplitRequest& r = out.request;
  r.leave_one_out = a.leave_one_out;
  r.explicit_test = !a.test.empty();
  if (!a.leave_one_out && !a.train.empty())
    for (const auto& n : names_of(a.train, "--train")) r.train.push_back(index_in(seq, n, "--train"));
  r.train_fraction = a.train_fraction;
  r.train_every = a.train_every;
  r.train_count = a.train_count;
  if (!a.rest.empty()) r.rest = index_in(seq, a.rest, "--rest");
  r.frame_names = seq.names;
  return out;
}

std::string cv_csv_of(const SkinningComparison& c) {
  std::string csv =
      "fold,method,setting,held_out_mean_error,standard_error,paired_standard_error,held_out_examples,chosen,chosen_by\n";
  for (const CvCandidateRow& r : c.cv_rows)
    csv += fmt::format("{},{},{},{:.8g},{:.4g},{:.4g},{},{},{}\n", r.fold, skinning_model_name(r.method),
                       csv_field(r.candidate.setting), r.candidate.error, r.candidate.standard_error,
                       r.candidate.paired_standard_error, r.candidate.example_errors.size(), r.chosen ? 1 : 0,
                       r.chosen_by);
  return csv;
}

std::string frames_csv_of(const SkinningComparison& c, const MeshSequence& seq) {
  std::string csv = "frame,split";
  for (auto m : c.methods) csv += ",mean_geometric_" + skinning_model_name(m);
  csv += "\n";
  for (size_t f = 0; f < seq.names.size(); ++f) {
    csv += csv_field(seq.names[f]) + "," + c.frame_split[f];
    for (size_t m = 0; m < c.methods.size(); ++m) csv += fmt::format(",{:.8g}", c.frame_error[m][f]);
    csv += "\n";
  }
  return csv;
}

std::string methods_csv_of(const SkinningComparison& c) {
  const double d = c.last.diagonal;
  std::string csv =
      "method,split,mean_geometric,max_geometric,mean_normal_deg,max_normal_deg,rms_vertex,e_rms,frames,fit_cpu_s\n";
  for (size_t m = 0; m < c.methods.size(); ++m)
    for (int s = 0; s < 2; ++s) {
      const DeviationStats& st = s == 0 ? c.train[m] : c.unseen[m];
      if (st.count == 0) continue;
      csv += fmt::format("{},{},{:.8g},{:.8g},{:.6g},{:.6g},{:.8g},{:.6g},{},{:.3f}\n", skinning_model_name(c.methods[m]),
                         s == 0 ? "train" : "unseen", st.mean_geometric(), st.max_geometric, st.mean_normal_deg(),
                         st.max_normal, st.rms_vertex(), st.e_rms(d), st.frames, c.fit_cpu[m]);
    }
  return csv;
}

std::string report_markdown(const EvalArgs& a, const SkinningComparison& c, const MeshSequence& seq,
                            const std::string& source, const FrameSplit& split, const SequenceEvaluationOptions& opt) {
  const double d = c.last.diagonal;
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
      source, split.protocol, a.bones, "(recovered: k-means on triangle rotation sequences + EM refinement + SSD alternation)",
      a.max_influences, seq.names[size_t(split.rest)], cv_description(opt.cv), seq.names[0], d, c.prepare_cpu,
      c.cv_setup_cpu);
  for (size_t m = 0; m < c.methods.size(); ++m)
    for (int s = 0; s < 2; ++s) {
      const DeviationStats& st = s == 0 ? c.train[m] : c.unseen[m];
      if (st.count == 0) continue;
      md += fmt::format("| {} | {} | {} | {:.6f} | {:.5f} | {:.4f} | {:.3f} | {:.1f} | {:.6f} | {:.4f} | {:.1f} |\n",
                        skinning_model_name(c.methods[m]), s == 0 ? "train" : "unseen", st.frames, st.mean_geometric(),
                        st.max_geometric, 100 * st.mean_geometric() / d, st.mean_normal_deg(), st.max_normal,
                        st.rms_vertex(), st.e_rms(d), c.fit_cpu[m]);
    }
  // All frames together, as Jacka's Table 1 reports (mean over every pose of the data set).
  md += "\nAll frames together (Jacka et al. Table 1 reports means over every pose of the data set):\n\n"
        "| method | mean geometric | max geometric | mean normal (°) | max normal (°) |\n|---|---|---|---|---|\n";
  for (size_t m = 0; m < c.methods.size(); ++m) {
    DeviationStats both = c.train[m];
    both.merge(c.unseen[m]);
    md += fmt::format("| {} | {:.6f} | {:.5f} | {:.3f} | {:.1f} |\n", skinning_model_name(c.methods[m]),
                      both.mean_geometric(), both.max_geometric, both.mean_normal_deg(), both.max_normal);
  }
  const SequenceEvaluation& last = c.last;
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
  md += fmt::format("\nTotal {:.1f} s.\n", c.seconds);
  return md;
}

void run_eval(const EvalArgs& a) {
  const MeshSequence all = read_inputs(a);
  SequenceEvaluationOptions opt = evaluation_options(a);
  const std::string source = a.inputs.size() == 1 && a.list.empty() ? a.inputs[0]
                             : fmt::format("{} mesh files", all.names.size());
  const SelectedFrames selected = select_frames(a, all, source);
  const MeshSequence& seq = selected.seq;
  const FrameSplit split = split_frames(int(seq.frames.size()), selected.request);
  opt.frame_faces = seq.frame_faces;
  opt.cv = parse_cv_scheme(a.cv, split.forecast);
  opt.cv.rule = parse_cv_rule(a.cv_rule);
  opt.cv.nesting = parse_cv_nesting(a.cv_nesting);
  check_comparison(int(seq.frames.size()), split, opt);
  if (a.save_posed && a.leave_one_out) throw InputError("--save-posed needs a single split (not --leave-one-out)");
  ensure_directory(a.out);
  if (a.save_posed)
    opt.on_posed = [&](SkinningModel m, int f, const Eigen::MatrixX3d& X) {
      const auto dir = std::filesystem::path(a.out) / "posed" / skinning_model_name(m);
      ensure_directory(dir);
      write_mesh(dir / (seq.names[static_cast<size_t>(f)] + ".obj"), X,
                 seq.frame_faces.empty() ? seq.F : seq.frame_faces[static_cast<size_t>(f)]);
    };
  ProgressBar bar("skin eval");
  const SkinningComparison c = compare_skinning_methods(seq.frames, seq.F, split, opt, bar.callback());
  bar.finish();
  const std::string md = report_markdown(a, c, seq, source, split, opt);
  const std::filesystem::path out(a.out);
  write_text_file(out / "skinning.csv", methods_csv_of(c));
  write_text_file(out / "skinning.md", md);
  write_text_file(out / "skinning_frames.csv", frames_csv_of(c, seq));
  write_text_file(out / "skinning_cv.csv", cv_csv_of(c));
  const double scale = a.color_scale > 0 ? a.color_scale : 0.01 * c.last.diagonal;
  for (size_t m = 0; m < c.methods.size(); ++m)
    write_mesh(out / ("unseen_error_" + skinning_model_name(c.methods[m]) + ".ply"), seq.frames[size_t(split.rest)],
               seq.frame_faces.empty() ? seq.F : seq.frame_faces[size_t(split.rest)],
               error_colors(c.per_vertex_unseen[m], scale));
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
