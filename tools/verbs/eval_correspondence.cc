// bodymodel eval-correspondence REG/ --truth TRUTH/ --out DIR [--pairs inter|intra|all]
//                               [--truth-scale 1000] [--truth-up x] [--subject-regex R]
//
// FAUST's correspondence protocol (registration/correspondence.h; docs/evaluation.md) on a data
// set whose meshes share one topology with ground-truth correspondence (FAUST, SCAPE): every
// registration REG/<stem>.ply (or .obj/.off; template topology, mm, +y up) is paired with
// TRUTH/<stem>.off (or .ply/.obj); a registration without a truth is refused, not skipped.
// Writes DIR/pairs.csv (per ordered pair), DIR/meshes.csv (per mesh: two-sided surface distance
// to its truth, folded triangles) and DIR/summary.csv (inter- and intra-subject pooled errors,
// cm).
#include <fmt/format.h>

#include <filesystem>
#include <map>
#include <regex>

#include "core/body_size.h"
#include "core/landmarks.h"
#include "core/error.h"
#include "core/geometry.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/mesh_io.h"
#include "core/makehuman.h"
#include "core/up_axis.h"
#include "registration/correspondence.h"
#include "registration/mesh_scan.h"
#include "registration/metrics.h"
#include "tools/console.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct CorrespondenceArgs {
  std::string reg, truth, out, pairs = "all", truth_up = "y", subject_regex = "^(.*)$", landmarks;
  double truth_scale = 1.0;
  int samples = 30000;
  bool vertex_errors = false;
  std::string location = "closest";
};

std::string cm(double mm) { return fmt::format("{:.3f}", mm / 10.0); }

}  // namespace

namespace {

void add_eval_correspondence_options(CLI::App* cmd, CorrespondenceArgs& a) {
  cmd->add_option("reg", a.reg,
                  "Folder of registrations <stem>.ply|.obj|.off (template topology, mm); each needs its truth")
      ->required();
  cmd->add_option("--truth", a.truth,
                  "Folder of truth meshes <stem>.off|.ply|.obj, one vertex numbering: vertex i the same "
                  "body point on every mesh")
      ->required();
  cmd->add_option("--out", a.out, "Output folder")->required();
  cmd->add_option("--pairs", a.pairs,
                  "Ordered pairs evaluated: 'inter' (different subjects), 'intra' (same subject, "
                  "different poses) or 'all'")
      ->check(CLI::IsMember({"inter", "intra", "all"}))
      ->capture_default_str();
  cmd->add_option("--truth-scale", a.truth_scale,
                  "Millimetres per truth unit (1000 for FAUST and SCAPE, in metres)")
      ->capture_default_str();
  cmd->add_option("--truth-up", a.truth_up,
                  "Axis the truth bodies stand along (x for SCAPE); rotated onto +y as "
                  "register-mesh/scanify --up do")
      ->capture_default_str();
  cmd->add_option("--subject-regex", a.subject_regex,
                  "Regular expression on a mesh's stem whose first group is the subject; pairs of "
                  "one subject are intra-subject. FAUST: 'tr_reg_(\\d\\d)\\d'; one person (SCAPE): "
                  "'^()'. Default: every mesh its own subject")
      ->capture_default_str();
  cmd->add_option("--samples", a.samples,
                  "Surface samples per side for the two-sided distance")
      ->capture_default_str();
  cmd->add_option("--landmarks", a.landmarks,
                  "A landmark file in the truth's vertex numbering (as register-mesh's): also the distance "
                  "from each registration's template landmark vertex to the truth's, per landmark "
                  "(landmarks.csv), e.g. nose_tip to see where the face landed")
      ->check(CLI::ExistingFile);
  cmd->add_option("--location", a.location,
                  "How a truth vertex is located on its registration: 'closest' (the closest surface point, the "
                  "protocol) or 'oriented' (the closest triangle facing the vertex's way: where limbs touch, a "
                  "diagnosis of how much of the error is the location landing on the other limb)")
      ->check(CLI::IsMember({"closest", "oriented"}))
      ->capture_default_str();
  cmd->add_flag("--vertex-errors", a.vertex_errors,
                "Also write OUT/vertices.csv: per truth vertex (rows) and mesh (columns), its mean error (cm) over "
                "the evaluated pairs that include the mesh (where a mesh's errors are, e.g. at its contacts)");
}

// Per landmark of --landmarks: how far the registration put the template's landmark vertex from
// the truth's (the file's entries read on each truth mesh, so vertex indices follow the pose).
struct LandmarkFigures {
  std::string csv, lines;
};

LandmarkFigures landmark_figures(const std::string& file, const std::vector<CorrespondenceMesh>& meshes,
                                 const std::vector<Mesh>& truth_meshes) {
  LandmarkFigures L;
  L.csv = "mesh,landmark,distance_mm\n";
  std::map<std::string, std::vector<std::pair<double, std::string>>> by_name;
  for (size_t k = 0; k < meshes.size(); ++k)
    for (const Landmark& l : read_mesh_landmarks(file, registration_landmarks(), truth_meshes[k].V)) {
      const double d = (meshes[k].registered.row(l.vertex).transpose() - l.target).norm();
      L.csv += fmt::format("{},{},{:.3f}\n", csv_field(meshes[k].id), csv_field(l.name), d);
      by_name[l.name].emplace_back(d, meshes[k].id);
    }
  for (const auto& [name, v] : by_name) {
    double mean = 0;
    for (const auto& [d, id] : v) mean += d / double(v.size());
    const auto worst = *std::max_element(v.begin(), v.end());
    L.lines += fmt::format("landmark {}: mean {:.1f} mm, max {:.1f} mm ({})\n", name, mean, worst.first, worst.second);
  }
  return L;
}

// OUT/vertices.csv: vertex, then one column of mean errors (cm) per mesh.
std::string vertex_error_csv(const std::vector<CorrespondenceMesh>& meshes, const CorrespondenceReport& report) {
  std::string csv = "vertex";
  for (const auto& m : meshes) csv += "," + csv_field(m.id);
  csv += "\n";
  const Eigen::MatrixXd& E = report.vertex_error_mean;
  for (Eigen::Index i = 0; i < E.rows(); ++i) {
    csv += std::to_string(i);
    for (Eigen::Index m = 0; m < E.cols(); ++m) csv += fmt::format(",{:.4f}", E(i, m) / 10.0);
    csv += "\n";
  }
  return csv;
}

// Each registration with its truth (by file stem). Every registration is evaluated or the run
// refuses: one left out without a word would change the pooled errors silently.
struct RegistrationPairs {
  std::map<std::string, fs::path> truths;
  std::vector<std::pair<std::string, fs::path>> found;  // stem, registration
};

RegistrationPairs pair_registrations(const CorrespondenceArgs& a, const fs::path& reg_dir, const fs::path& truth_dir) {
  RegistrationPairs P;
  std::map<std::string, fs::path>& truths = P.truths;
  std::vector<std::pair<std::string, fs::path>>& found = P.found;
  // Truths by stem.
  for (const auto& e : fs::directory_iterator(truth_dir)) {
    std::string ext = e.path().extension().string();
    for (auto& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext == ".off" || ext == ".ply" || ext == ".obj") truths[e.path().stem().string()] = e.path();
  }
  // Every registration is evaluated or the run refuses: one left out without a word would
  // change the pooled errors silently.
  std::map<std::string, fs::path> by_stem;
  std::vector<fs::path> without_truth;
  for (const auto& e : fs::directory_iterator(reg_dir)) {
    std::string ext = e.path().extension().string();
    for (auto& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".ply" && ext != ".obj" && ext != ".off") continue;
    const std::string stem = e.path().stem().string();
    // <stem>.detailed.ply and the like are derived outputs; '.'-names are temporaries.
    if (stem.empty() || stem[0] == '.' || stem.find('.') != std::string::npos) continue;
    const auto [it, inserted] = by_stem.emplace(stem, e.path());
    if (!inserted)
      throw InputError("'" + e.path().string() + "' and '" + it->second.string() +
                       "': two registrations of '" + stem + "'; keep one");
    if (truths.count(stem)) found.emplace_back(stem, e.path());
    else without_truth.push_back(e.path());
  }
  std::sort(found.begin(), found.end());
  std::sort(without_truth.begin(), without_truth.end());
  if (!without_truth.empty())
    throw InputError("'" + without_truth.front().string() + "': no truth <stem>.off|.ply|.obj for it in '" +
                     a.truth + "'" +
                     (without_truth.size() > 1 ? fmt::format(" ({} of {} registrations have none)",
                                                              without_truth.size(), by_stem.size())
                                               : std::string()) +
                     "; every registration in '" + a.reg + "' is evaluated: add its truth or move it out");
  if (found.size() < 2)
    throw InputError("'" + a.reg + "': found " + std::to_string(found.size()) +
                     " registrations <stem>.ply|.obj|.off with a truth <stem>.off|.ply|.obj in '" +
                     a.truth + "'; need at least two");

  return P;
}

// Per mesh: two-sided surface distance to its truth and folds (meshes.csv).
struct PerMeshFigures {
  std::string csv;
  std::vector<double> two_sided;
  std::vector<int> folded, flipped;
};

PerMeshFigures per_mesh_figures(const CorrespondenceArgs& a, const std::vector<CorrespondenceMesh>& meshes,
                                const std::vector<Mesh>& truth_meshes, const Eigen::MatrixX3i& reg_F, const Mesh& rest,
                                const CorrespondenceReport& report) {
  PerMeshFigures P;
  std::string& mesh_csv = P.csv;
  std::vector<double>& two_sided = P.two_sided;
  std::vector<int>& folded = P.folded;
  std::vector<int>& flipped = P.flipped;
  cli::ProgressBar mesh_bar("surface distance and folds per mesh");
  mesh_csv =
      "mesh,subject,registered_to_truth_mm,truth_to_registered_mm,two_sided_mm,"
      "registered_to_truth_p95_mm,truth_to_registered_p95_mm,truth_vertex_location_mm,"
      "locally_folded,flipped_against_truth\n";
  two_sided.resize(meshes.size());
  folded.resize(meshes.size());
  flipped.resize(meshes.size());
  for (size_t k = 0; k < meshes.size(); ++k) {
    const MeshScanDistance d = mesh_scan_distance(meshes[k].registered, reg_F, truth_meshes[k],
                                                  nullptr, a.samples);
    const std::vector<char> f = locally_folded_triangles(meshes[k].registered, rest.V, reg_F);
    folded[k] = int(std::count(f.begin(), f.end(), 1));
    flipped[k] = d.flipped_against_scan;
    two_sided[k] = d.two_sided_mean;
    mesh_csv += fmt::format("{},{},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{},{}\n",
                            csv_field(meshes[k].id), csv_field(meshes[k].subject), d.registered_to_scan_mean,
                            d.scan_to_registered_mean, d.two_sided_mean,
                            d.registered_to_scan_p95, d.scan_to_registered_p95,
                            report.location_distance_mean[k], folded[k], flipped[k]);
    mesh_bar.update(double(k + 1) / double(meshes.size()), meshes[k].id);
  }
  mesh_bar.finish();

  return P;
}

// The registrations and their truths in the project's frame, checked for topology, unit and subject.
struct ReadMeshes {
  std::vector<CorrespondenceMesh> meshes;
  std::vector<Mesh> truth_meshes;
  Eigen::MatrixX3i reg_F;
};

ReadMeshes read_correspondence_meshes(const CorrespondenceArgs& a, const RegistrationPairs& paired, const Mesh& rest,
                                      const Eigen::Matrix3d& up, const std::regex& subject_re) {
  const std::map<std::string, fs::path>& truths = paired.truths;
  const std::vector<std::pair<std::string, fs::path>>& found = paired.found;
  ReadMeshes R;
  std::vector<CorrespondenceMesh>& meshes = R.meshes;
  std::vector<Mesh>& truth_meshes = R.truth_meshes;
  Eigen::MatrixX3i& reg_F = R.reg_F;
  meshes.resize(found.size());
  truth_meshes.resize(found.size());
  cli::ProgressBar read_bar(fmt::format("read {} registrations and truths", found.size()));
  for (size_t k = 0; k < found.size(); ++k) {
    const auto& [stem, reg_path] = found[k];
    Mesh r = read_mesh(reg_path);
    if (r.V.rows() != rest.V.rows() || r.F != rest.F)
      throw InputError("'" + reg_path.string() + "': expected a registration in the template's "
                       "topology (" + std::to_string(rest.V.rows()) + " vertices, " +
                       std::to_string(rest.F.rows()) + " triangles), found " +
                       std::to_string(r.V.rows()) + " vertices and " +
                       std::to_string(r.F.rows()) + " triangles");
    Mesh t = read_mesh(truths.at(stem));
    if (k == 0) {
      reg_F = r.F;
    } else if (t.V.rows() != meshes[0].truth.rows()) {
      // The protocol needs vertex i to be one body point on every truth; the faces are used
      // only for each mesh's own surface distance (SCAPE's files list them differently).
      throw InputError("'" + truths.at(stem).string() + "': " + std::to_string(t.V.rows()) +
                       " vertices; '" + truths.at(found[0].first).string() + "' has " +
                       std::to_string(meshes[0].truth.rows()) +
                       ": the truths must share one vertex numbering");
    }
    t.V = to_project_frame(t.V, a.truth_scale, up);
    check_body_size(t.V, "'" + truths.at(stem).string() + "'", "--truth-scale", a.truth_scale);
    const double ratio = bounding_box_diagonal(t.V) / bounding_box_diagonal(r.V);
    if (ratio > 2.0 || ratio < 0.5)
      throw InputError("'" + truths.at(stem).string() + "' is " + fmt::format("{:.3g}", ratio) +
                       " times the size of its registration after --truth-scale " +
                       fmt::format("{}", a.truth_scale) +
                       ": wrong --truth-scale (mm per truth unit; 1000 for metres)?");
    std::smatch m;
    if (!std::regex_search(stem, m, subject_re) || m.size() < 2)
      throw InputError("--subject-regex '" + a.subject_regex + "' does not match '" + stem +
                       "' with a capture group (the subject)");
    meshes[k].id = stem;
    meshes[k].subject = m[1].str();
    meshes[k].truth = t.V;
    meshes[k].registered = r.V;
    if (a.location == "oriented")
      meshes[k].truth_normals = (signed_volume(t.V, t.F) < 0 ? -1.0 : 1.0) * vertex_normals(t.V, t.F);
    truth_meshes[k] = std::move(t);
    read_bar.update(double(k + 1) / double(found.size()), stem);
  }
  read_bar.finish();
  return R;
}

void run_eval_correspondence(CorrespondenceArgs& a) {
  if (!(a.truth_scale > 0) || !std::isfinite(a.truth_scale))
    throw InputError("--truth-scale must be a positive number of millimetres per truth unit");
  if (a.samples < 100) throw InputError("--samples must be at least 100");
  const Eigen::Matrix3d up = up_axis_rotation(a.truth_up, "--truth-up");
  std::regex subject_re;
  try {
    subject_re = std::regex(a.subject_regex);
  } catch (const std::regex_error& e) {
    throw InputError("--subject-regex '" + a.subject_regex + "': " + e.what());
  }
  const fs::path reg_dir = a.reg, truth_dir = a.truth, out = a.out;
  for (const auto& [d, name] : {std::pair{reg_dir, "registration"}, {truth_dir, "--truth"}})
    if (!fs::is_directory(d))
      throw InputError(std::string(name) + " folder '" + d.string() + "' does not exist");
  const RegistrationPairs paired = pair_registrations(a, reg_dir, truth_dir);
  MakeHuman mh = MakeHuman::load();
  const Mesh rest = mh.body(MacroSettings{}).mesh;
  ReadMeshes read = read_correspondence_meshes(a, paired, rest, up, subject_re);
  const std::vector<CorrespondenceMesh>& meshes = read.meshes;
  const std::vector<Mesh>& truth_meshes = read.truth_meshes;
  const Eigen::MatrixX3i& reg_F = read.reg_F;

  CorrespondenceOptions options;
  options.pairs = a.pairs == "inter"   ? PairSelection::inter
                  : a.pairs == "intra" ? PairSelection::intra
                                        : PairSelection::all;
  options.oriented_location = a.location == "oriented";
  cli::ProgressBar bar("correspondence");
  const CorrespondenceReport report = evaluate_correspondence(meshes, reg_F, options, bar.callback());
  bar.finish(fmt::format("{} pairs", report.pairs.size()));

  const PerMeshFigures figures = per_mesh_figures(a, meshes, truth_meshes, reg_F, rest, report);
  const std::string& mesh_csv = figures.csv;
  const std::vector<double>& two_sided = figures.two_sided;
  const std::vector<int>& folded = figures.folded;
  const std::vector<int>& flipped = figures.flipped;
  std::string pair_csv = "a,b,subject_a,subject_b,kind,mean_cm,median_cm,p95_cm,max_cm\n";
  for (const auto& p : report.pairs)
    pair_csv += fmt::format("{},{},{},{},{},{},{},{},{}\n", csv_field(meshes[p.a].id), csv_field(meshes[p.b].id),
                            csv_field(meshes[p.a].subject), csv_field(meshes[p.b].subject),
                            p.inter ? "inter" : "intra", cm(p.stats.mean), cm(p.stats.median),
                            cm(p.stats.p95), cm(p.stats.max));
  std::string summary = "kind,pairs,errors,mean_cm,median_cm,p95_cm,max_cm\n";
  for (const auto& [kind, s] : {std::pair{"inter", report.inter}, {"intra", report.intra}})
    if (s.pairs > 0)
      summary += fmt::format("{},{},{},{},{},{},{}\n", kind, s.pairs, s.count, cm(s.mean),
                             cm(s.median), cm(s.p95), cm(s.max));
  double ts_mean = 0, ts_max = 0;
  int fold_total = 0, fold_meshes = 0, flip_total = 0;
  for (size_t k = 0; k < meshes.size(); ++k) {
    ts_mean += two_sided[k] / double(meshes.size());
    ts_max = std::max(ts_max, two_sided[k]);
    fold_total += folded[k];
    fold_meshes += folded[k] > 0;
    flip_total += flipped[k];
  }
  summary += fmt::format("# meshes {}: two-sided surface distance mean {:.3f} mm (worst mesh "
                         "{:.3f}); locally folded triangles {} in {} meshes; flipped against "
                         "the truth surface {}\n",
                         meshes.size(), ts_mean, ts_max, fold_total, fold_meshes, flip_total);
  const LandmarkFigures lm = a.landmarks.empty() ? LandmarkFigures{} : landmark_figures(a.landmarks, meshes, truth_meshes);
  ensure_directory(out);
  if (!a.landmarks.empty()) write_text_file(out / "landmarks.csv", lm.csv);
  write_text_file(out / "pairs.csv", pair_csv);
  write_text_file(out / "meshes.csv", mesh_csv);
  write_text_file(out / "summary.csv", summary);
  if (a.vertex_errors) write_text_file(out / "vertices.csv", vertex_error_csv(meshes, report));
  for (const auto& [kind, s] : {std::pair{"inter", report.inter}, {"intra", report.intra}})
    if (s.pairs > 0)
      fmt::print("{}-subject ({} ordered pairs): mean {} cm, median {} cm, p95 {} cm, max {} cm\n",
                 kind, s.pairs, cm(s.mean), cm(s.median), cm(s.p95), cm(s.max));
  fmt::print("{} meshes: two-sided surface distance mean {:.2f} mm (worst {:.2f}); locally "
             "folded triangles {} in {} meshes; flipped against the truth surface {}\n",
             meshes.size(), ts_mean, ts_max, fold_total, fold_meshes, flip_total);
  fmt::print("{}", lm.lines);
}

}  // namespace

BODYMODEL_VERB(add_eval_correspondence_verb) {
  auto a = std::make_shared<CorrespondenceArgs>();
  auto* cmd = app.add_subcommand(
      "eval-correspondence",
      "FAUST's correspondence protocol on registrations of a data set with ground-truth\n"
      "correspondence (FAUST, SCAPE): for an ordered pair (A, B), each truth vertex of A is\n"
      "located on A's registration (closest surface point, barycentric), carried to B's\n"
      "registration, and its distance to B's truth vertex is the error. Reports mean, median,\n"
      "p95 and max (cm) per pair and pooled over inter-subject pairs (different people) and\n"
      "intra-subject pairs (one person, different poses); per mesh the two-sided surface\n"
      "distance to its truth and folded triangles.\n"
      "Writes OUT/pairs.csv, OUT/meshes.csv, OUT/summary.csv (and OUT/landmarks.csv with --landmarks).\n"
      "Example (FAUST, in metres; tr_reg_NNN: subject = NNN div 10):\n"
      "  bodymodel eval-correspondence reg/ --truth faust/ --truth-scale 1000 \\\n"
      "      --subject-regex 'tr_reg_(\\d\\d)\\d' --out eval/");
  add_eval_correspondence_options(cmd, *a);
  cmd->callback([a] { run_eval_correspondence(*a); });
}

}  // namespace bodymodel
