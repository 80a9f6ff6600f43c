// `bodymodel markers simulate|clean|deform`: dense-marker captures (Park & Hodgins 2006, issue 38).
// simulate: a realistic C3D capture (and its truth) from a mesh sequence; clean: label, merge,
// fill and smooth a capture (markers/clean.h), with a JSON report; deform: drive the reference
// mesh by cleaned markers (markers/deform.h) beside SSD and MWE rigs, against the truth meshes.
#include <fmt/format.h>

#include <memory>

#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/json_text.h"
#include "core/io/mesh_io.h"
#include "markers/c3d.h"
#include "markers/clean.h"
#include "markers/deform_evaluation.h"
#include "markers/simulate.h"
#include "markers/trc.h"
#include "tools/console.h"
#include "tools/pipeline/marker_pictures.h"
#include "tools/pipeline/output_folder.h"
#include "tools/verb.h"
#include "tools/verbs/skin_common.h"

namespace bodymodel::cli {
namespace {

CLI::App* markers_group(CLI::App& app) {
  for (CLI::App* s : app.get_subcommands(std::function<bool(CLI::App*)>()))
    if (s->get_name() == "markers") return s;
  CLI::App* s = app.add_subcommand("markers", "Dense-marker captures (Park & Hodgins 2006): simulate a C3D capture "
                                              "from a mesh sequence, clean a capture (label, merge, fill, smooth), drive a skin by it");
  s->require_subcommand(1);
  return s;
}

struct SimulateArgs {
  std::vector<std::string> meshes;
  std::string out, truth_format = "trc";
  SimulateOptions o;
  bool force = false;
};

std::string pieces_table(const SimulatedCapture& s) {
  std::string csv = csv_row({"piece", "marker", "first_frame", "last_frame"}) + "\n";
  for (const auto& p : s.pieces)
    csv += csv_row({p.label, p.marker < 0 ? "ghost" : s.truth.labels[p.marker], std::to_string(p.first),
                    std::to_string(p.last)}) + "\n";
  return csv;
}

void run_simulate(const SimulateArgs& a) {
  if (a.truth_format != "trc" && a.truth_format != "c3d")
    throw InputError("--truth-format must be trc or c3d, found '" + a.truth_format + "'");
  const MeshSequence seq = a.meshes.size() == 1 && std::filesystem::is_directory(a.meshes[0])
                               ? read_mesh_sequence(a.meshes[0])
                               : read_mesh_files(std::vector<std::filesystem::path>(a.meshes.begin(), a.meshes.end()));
  StagedFolder out(a.out, a.force);
  ProgressBar bar("markers simulate");
  const SimulatedCapture s = simulate_capture(seq.frames, seq.F, a.o, [&](double f) { bar.update(f); });
  bar.finish();
  write_c3d(out / "capture.c3d", s.capture);
  write_markers(out / ("truth." + a.truth_format), s.truth);
  write_text_file(out / "pieces.csv", pieces_table(s));
  const nlohmann::json summary = {
      {"verb", "markers simulate"}, {"meshes", seq.frames.size()}, {"frames", s.truth.frame_count()},
      {"rate", a.o.rate}, {"markers", s.truth.marker_count()}, {"spacing_mm", s.spacing_mm},
      {"pieces", s.pieces.size()}, {"ghosts", a.o.ghosts}, {"occluded_fraction", s.occluded},
      {"missing_fraction", s.missing}, {"random_gaps", s.random_gaps}, {"broken", s.broken}, {"seed", a.o.seed}};
  write_text_file(out / "simulate.json", json_text(summary, 1) + "\n");
  out.commit();
  info(fmt::format("{} markers ({:.0f} mm apart), {} frames at {} Hz: {:.1f}% occluded, {:.1f}% missing with {} added gaps, "
                   "{} broken, {} unlabelled pieces → {}",
                   s.truth.marker_count(), s.spacing_mm, s.truth.frame_count(), a.o.rate, 100 * s.occluded,
                   100 * s.missing, s.random_gaps, s.broken, s.pieces.size(), a.out));
}

void add_simulate(CLI::App* group) {
  auto* cmd = group->add_subcommand(
      "simulate",
      "Simulate a dense-marker capture from a mesh sequence with truth (one folder or the frame files in order):\n"
      "markers on the first frame, a ring of cameras, gaps, noise, unlabelled pieces, ghosts. Writes\n"
      "OUT/capture.c3d, OUT/truth.trc (every marker, every frame), OUT/pieces.csv, OUT/simulate.json.\n"
      "  bodymodel markers simulate ../shared/data/animations/vlasic-jumping --out sim/");
  auto a = std::make_shared<SimulateArgs>();
  cmd->add_option("meshes", a->meshes, "Mesh frames (.obj/.ply/.off) or one folder of them")->required();
  cmd->add_option("--out", a->out, "Output folder")->required();
  cmd->add_option("--markers", a->o.markers, "Number of markers")->capture_default_str();
  cmd->add_option("--radius", a->o.marker_radius_mm, "Marker radius (mm): offset along the normal")->capture_default_str();
  cmd->add_option("--unit-mm", a->o.mm_per_unit, "Millimetres per mesh unit (1000: metres)")->capture_default_str();
  cmd->add_option("--mesh-rate", a->o.mesh_rate, "Frames per second of the meshes")->capture_default_str();
  cmd->add_option("--rate", a->o.rate, "Capture rate (frames per second; meshes interpolated in time)")->capture_default_str();
  cmd->add_option("--cameras", a->o.cameras, "Cameras on the ring")->capture_default_str();
  cmd->add_option("--noise", a->o.noise_mm, "Noise (mm, standard deviation per coordinate)")->capture_default_str();
  cmd->add_option("--missing", a->o.missing, "Fraction of samples missing (occlusion, then random gaps)")->capture_default_str();
  cmd->add_option("--gap-min", a->o.gap_min, "Shortest random gap (frames)")->capture_default_str();
  cmd->add_option("--gap-max", a->o.gap_max, "Longest random gap (frames)")->capture_default_str();
  cmd->add_option("--broken", a->o.broken, "Fraction of trajectories broken where a neighbour passes closest")->capture_default_str();
  cmd->add_option("--ghosts", a->o.ghosts, "Ghost markers (short spurious trajectories)")->capture_default_str();
  cmd->add_option("--seed", a->o.seed, "Random seed")->capture_default_str();
  cmd->add_option("--truth-format", a->truth_format, "trc or c3d")->capture_default_str();
  cmd->add_flag("--force", a->force, "Replace an existing output folder");
  cmd->callback([a] { run_simulate(*a); });
}

struct CleanArgs {
  std::string in, out, report, truth;
  CleanOptions o;
};

void run_clean(const CleanArgs& a) {
  std::string ext = std::filesystem::path(a.out).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  if (ext != ".c3d" && ext != ".trc") throw InputError("--out must name a .c3d or .trc file, found '" + a.out + "'");
  const MarkerData capture = read_markers(a.in);
  const MarkerData truth = a.truth.empty() ? MarkerData() : read_markers(a.truth);
  ProgressBar bar("markers clean");
  const CleanResult r = clean_markers(capture, a.o, [&](double f) { bar.update(f); });
  bar.finish();
  nlohmann::json report = clean_report_json(r.report);
  report["input"] = a.in;
  std::string extra;
  if (!a.truth.empty()) {
    const CleanEvaluation e = evaluate_cleaning(capture, r, truth);
    report["evaluation"] = evaluation_json(e);
    extra = fmt::format("; against the truth: {} wrong merges, {} pieces missed, median fill error {:.2f} mm "
                        "(spline {:.2f} mm on the same holes, ratio {:.2f})",
                        e.wrong_merges, e.missed_pieces, e.median_fill_mm, e.median_spline_mm, e.ratio_to_spline);
  }
  const std::string report_path = a.report.empty() ? (std::filesystem::path(a.out).replace_extension(".json").string()) : a.report;
  write_markers(a.out, r.cleaned);
  write_text_file(report_path, json_text(report, 1) + "\n");
  info(clean_summary_line(r.report) + extra + " → " + a.out);
}

void add_clean(CLI::App* group) {
  auto* cmd = group->add_subcommand(
      "clean",
      "Clean a capture (.c3d or .trc; labelled markers complete in the reference frame, unlabelled pieces\n"
      "named '*N'): merge the pieces into the markers, fill holes from the neighbours in local frames,\n"
      "smooth. Writes every labelled marker at every frame, and a JSON report (gaps, merges).\n"
      "  bodymodel markers clean sim/capture.c3d --out clean.trc --truth sim/truth.trc");
  auto a = std::make_shared<CleanArgs>();
  cmd->add_option("in", a->in, "Capture (.c3d or .trc)")->required();
  cmd->add_option("--out", a->out, "Cleaned capture (.c3d or .trc)")->required();
  cmd->add_option("--report", a->report, "Report (JSON; default: OUT with the extension .json)");
  cmd->add_option("--truth", a->truth, "Truth (every marker at every frame): adds wrong merges and fill errors to the report");
  cmd->add_option("--reference-frame", a->o.reference_frame, "Frame (0-based) of the marker surface")->capture_default_str();
  cmd->add_option("--neighbours", a->o.neighbours, "Neighbours of a marker (its one-ring)")->capture_default_str();
  cmd->add_option("--merge-tolerance", a->o.merge_tolerance, "a1: merge radius / mean neighbour distance")->capture_default_str();
  cmd->add_option("--piece-tolerance", a->o.piece_tolerance, "a2: whole-piece radius / mean neighbour distance")->capture_default_str();
  cmd->add_option("--model-tolerance", a->o.model_tolerance,
                  "Undo a merge the neighbourhood models put farther than this · mean neighbour distance, when another "
                  "marker's models explain the piece better (0 = never)")
      ->capture_default_str();
  cmd->add_option("--part-rigidity", a->o.part_rigidity,
                  "Markers whose distance varies by less (mm, std over time) share a rigid part, which predicts a "
                  "missing marker before its neighbours do (0 = no parts)")
      ->capture_default_str();
  cmd->add_option("--piece-rigidity", a->o.piece_rigidity,
                  "The same for a piece left and the markers moving with it (mm), which place it in the reference frame")
      ->capture_default_str();
  cmd->add_option("--part-size", a->o.part_size, "Largest rigid part of a marker (its steadiest nearby markers)")->capture_default_str();
  cmd->add_option("--part-rounds", a->o.part_rounds,
                  "Rounds matching the pieces left by where their own rigid part puts them in the reference frame (0 = none)")
      ->capture_default_str();
  cmd->add_option("--part-check", a->o.part_check,
                  "Check merges against the distances to the marker's rigid part: refuse a piece another nearby missing "
                  "marker's part explains better, undo a piece under 12 frames farther than this · --part-rigidity (0 = off)")
      ->capture_default_str();
  cmd->add_option("--model-rounds", a->o.model_rounds, "Rounds matching the pieces left by the neighbourhood models (0 = none)")
      ->capture_default_str();
  cmd->add_option("--smooth", a->o.smooth_iterations, "Smoothing passes in the local frame (0 = none)")->capture_default_str();
  cmd->callback([a] { run_clean(*a); });
}

struct DeformArgs {
  std::string markers, out, clean_report;
  double filled_weight = 0.1, filled_halflife = 10;
  std::vector<std::string> meshes;  // one folder, or the frame files in order
  double unit_mm = 1000;
  int write_every = 0;
  bool force = false;
  MarkerDeformOptions o;
};

std::string deform_table(const MarkerDeformComparison& r) {
  std::vector<std::string> header = {"mesh_frame", "capture_frame"};
  for (const auto& e : r.errors) header.push_back(e.method + "_mean_mm");
  std::string csv = csv_row(header) + "\n";
  for (size_t k = 0; k < r.test_frames.size(); ++k) {
    std::vector<std::string> row = {std::to_string(r.test_meshes[k]), std::to_string(r.test_frames[k])};
    for (const auto& e : r.errors) row.push_back(fmt::format("{:.4f}", e.frame_mean[k]));
    csv += csv_row(row) + "\n";
  }
  return csv;
}

void run_deform(const DeformArgs& a) {
  if (!(a.unit_mm > 0)) throw InputError("--unit-mm must be positive");
  const MarkerData markers = read_markers(a.markers);
  MarkerDeformOptions o = a.o;
  if (!a.clean_report.empty())
    o.confidence = filled_sample_confidence(markers, read_clean_gaps(a.clean_report), a.filled_weight, a.filled_halflife);
  MeshSequence seq = a.meshes.size() == 1 && std::filesystem::is_directory(a.meshes[0])
                         ? read_mesh_sequence(a.meshes[0])
                         : read_mesh_files(std::vector<std::filesystem::path>(a.meshes.begin(), a.meshes.end()));
  for (auto& V : seq.frames) V *= a.unit_mm;
  StagedFolder out(a.out, a.force);
  ProgressBar bar("markers deform");
  const MarkerDeformComparison r = compare_marker_skins(seq.frames, seq.F, markers, o, bar.callback());
  bar.finish();
  nlohmann::json errors = nlohmann::json::object();
  std::string line;
  for (const auto& e : r.errors) {
    errors[e.method] = {{"mean_mm", e.mean}, {"max_mm", e.max}};
    line += fmt::format("{}{} {:.2f} / {:.1f}", line.empty() ? "" : ", ", e.method, e.mean, e.max);
  }
  nlohmann::json summary = {
      {"verb", "markers deform"}, {"markers", a.markers},
      {"meshes", a.meshes.size() == 1 ? nlohmann::json(a.meshes[0]) : nlohmann::json(a.meshes)}, {"parts", a.o.parts},
      {"mesh_rate", a.o.mesh_rate}, {"train_meshes", r.train_meshes}, {"test_meshes", r.test_meshes},
      {"test_frames", r.test_frames}, {"errors", errors}};
  if (!a.clean_report.empty())
    summary["confidence"] = {{"clean_report", a.clean_report}, {"filled_weight", a.filled_weight},
                             {"filled_halflife", a.filled_halflife}, {"rbf_min_confidence", a.o.skin.rbf_min_confidence},
                             {"filled_samples", (o.confidence.array() < 1).count()}};
  write_text_file(out / "deform.json", json_text(summary, 1) + "\n");
  write_text_file(out / "errors.csv", deform_table(r));
  for (int f = 0; a.write_every > 0 && f < markers.frame_count(); f += a.write_every) {
    const Eigen::VectorXd trust = o.confidence.size() ? Eigen::VectorXd(o.confidence.row(f).transpose()) : Eigen::VectorXd();
    const Eigen::MatrixX3d V = deform_by_markers(r.skin, marker_frame(markers, f), MarkerSkinStage::full, trust);
    write_mesh(out / fmt::format("park_{:05d}.obj", f), V / a.unit_mm, seq.F);
  }
  out.commit();
  info(fmt::format("{} held-out frames, mean / max vertex error (mm): {} → {}", r.test_frames.size(), line, a.out));
}

void add_deform(CLI::App* group) {
  auto* cmd = group->add_subcommand(
      "deform",
      "Drive the reference mesh (frame 0 of MESHES) by cleaned markers with Park & Hodgins' model (rigid\n"
      "parts, a quadratic deformation each, an RBF residual), beside SSD and MWE rigs driven by a skeleton\n"
      "fitted to the markers; even mesh frames train, odd ones are held out and compared with the truth.\n"
      "Writes OUT/deform.json, OUT/errors.csv (and OUT/park_FFFFF.obj with --write-every).\n"
      "  bodymodel markers deform clean.trc --meshes ../shared/data/animations/vlasic-jumping --out deform/");
  auto a = std::make_shared<DeformArgs>();
  cmd->add_option("markers", a->markers, "Cleaned capture (.c3d or .trc): every marker labelled and present")->required();
  cmd->add_option("--meshes", a->meshes, "Folder of the truth mesh frames, or the frame files in order (frame 0: the reference pose)")
      ->required();
  cmd->add_option("--out", a->out, "Output folder")->required();
  cmd->add_option("--mesh-rate", a->o.mesh_rate, "Frames per second of the meshes")->capture_default_str();
  cmd->add_option("--unit-mm", a->unit_mm, "Millimetres per mesh unit (1000: metres)")->capture_default_str();
  cmd->add_option("--parts", a->o.parts, "Rigid parts (recovered from the training meshes)")->capture_default_str();
  cmd->add_option("--max-distance", a->o.max_marker_distance, "Largest distance (mm) of a reference marker from the mesh")->capture_default_str();
  cmd->add_option("--rbf-ridge", a->o.skin.rbf_ridge, "Added to the RBF kernel matrix's diagonal (phi(0) = 2/3; 0: exact interpolation)")
      ->capture_default_str();
  cmd->add_option("--clean-report", a->clean_report,
                  "The markers clean report of MARKERS: the samples its gaps filled get a lower confidence in the fits "
                  "(Park's and the rigs' skeleton), those far from a seen sample none in the RBF residual (a departure "
                  "from the paper; without it every sample is trusted)");
  cmd->add_option("--filled-weight", a->filled_weight, "With --clean-report: a filled sample's weight next to a seen one, in (0, 1]")
      ->capture_default_str();
  cmd->add_option("--filled-halflife", a->filled_halflife,
                  "With --clean-report: frames from the nearest seen sample over which a filled sample's weight halves")
      ->capture_default_str();
  cmd->add_option("--rbf-min-confidence", a->o.skin.rbf_min_confidence,
                  "With --clean-report: samples of lower confidence are left out of the RBF residual")
      ->capture_default_str();
  cmd->add_option("--write-every", a->write_every, "Write Park's mesh every N capture frames (0: none)")->capture_default_str();
  cmd->add_flag("--force", a->force, "Replace an existing output folder");
  cmd->callback([a] { run_deform(*a); });
}

}  // namespace

BODYMODEL_VERB(add_markers_verb) {
  CLI::App* group = markers_group(app);
  add_simulate(group);
  add_clean(group);
  add_deform(group);
}

}  // namespace bodymodel::cli
