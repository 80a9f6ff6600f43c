// bodymodel demo --out out/ : the main job. Every stage runs as a subprocess of this executable
// (its log in OUT/logs/), then the pictures and OUT/report.html are made here.
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>

#include <algorithm>
#include <functional>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <thread>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/mesh_io.h"
#include "tools/console.h"
#include "tools/pipeline/dressed_pictures.h"
#include "tools/pipeline/marker_pictures.h"
#include "tools/pipeline/output_folder.h"
#include "tools/render/render.h"
#include "tools/report/html.h"
#include "tools/viewer/viewer_assets.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct DemoArgs {
  std::string out = "out";
  bool force = false;
  int crowd = 4;
};

struct StageResult {
  std::string name;
  double seconds = 0;
  int exit_code = 0;
  std::string log;
};

std::string last_line(const fs::path& log) {
  std::ifstream in(log);
  std::string line, last;
  while (std::getline(in, line)) {
    // Progress bars redraw with \r: keep the text after the last one.
    auto cr = line.find_last_of('\r');
    if (cr != std::string::npos) line = line.substr(cr + 1);
    if (!line.empty()) last = line;
  }
  return last;
}

// Runs this executable with `args`, stdout and stderr to `log`; shows the stage's last log line
// while it runs (on a terminal).
StageResult run_stage(int index, int total, const std::string& name, const std::vector<std::string>& args,
                      const fs::path& log) {
  StageResult r{name, 0, 0, log.string()};
  const bool tty = isatty(STDERR_FILENO);
  const std::string head = fmt::format("[{:2d}/{}] {:<34}", index, total, name);
  if (!tty) fmt::print(stderr, "{} ...\n", head);
  auto t0 = std::chrono::steady_clock::now();
  pid_t pid = fork();
  if (pid < 0) throw InputError("demo: cannot start a stage (fork failed)");
  if (pid == 0) {
    int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      dup2(fd, STDOUT_FILENO);
      dup2(fd, STDERR_FILENO);
      ::close(fd);
    }
    std::vector<std::string> full{"bodymodel"};
    full.insert(full.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& s : full) argv.push_back(s.data());
    argv.push_back(nullptr);
    execv("/proc/self/exe", argv.data());
    _exit(127);
  }
  int status = 0;
  while (true) {
    pid_t w = waitpid(pid, &status, WNOHANG);
    if (w == pid) break;
    if (tty) {
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::string l = last_line(log);
      if (l.size() > 60) l = l.substr(0, 60);
      fmt::print(stderr, "\r\033[K{} {:5.0f} s  {}", head, s, l);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  if (tty) fmt::print(stderr, "\r\033[K");
  fmt::print(stderr, "{} {:5.0f} s  {}\n", head, r.seconds,
             r.exit_code == 0 ? "ok" : fmt::format("FAILED (exit {}): {}", r.exit_code, last_line(log)));
  return r;
}

// Per-vertex registration error (registered vs truth, same vertex order) on the truth body.
void registration_pictures(const fs::path& out, const std::vector<std::string>& ids, double scale_mm) {
  std::vector<Eigen::MatrixX3d> meshes, colors;
  Eigen::MatrixX3i F;
  for (auto& id : ids) {
    const fs::path reg = out / "reg" / (id + ".ply"), truth = out / "db" / "truth" / (id + ".ply");
    std::error_code ec;
    if (!fs::exists(reg, ec) || !fs::exists(truth, ec)) continue;
    Mesh r = read_mesh(reg), t = read_mesh(truth);
    if (r.V.rows() != t.V.rows()) continue;
    meshes.push_back(t.V);
    colors.push_back(heat_colors((r.V - t.V).rowwise().norm(), 0, scale_mm));
    F = t.F;
  }
  if (meshes.empty()) return;
  Image row = render_row(meshes, F, colors, 220, 440);
  Image img(row.width, 440 + 24);
  img.paste(row, 0, 0);
  img.paste(heat_colorbar(row.width - 40, 12), 20, 446);
  img.save_png(out / "pictures" / "registration_error.png");
}

void row_picture(const std::vector<fs::path>& files, const fs::path& png) {
  std::vector<Eigen::MatrixX3d> meshes;
  Eigen::MatrixX3i F;
  for (auto& f : files) {
    std::error_code ec;
    if (!fs::exists(f, ec)) continue;
    Mesh m = read_mesh(f);
    meshes.push_back(m.V);
    F = m.F;
  }
  if (!meshes.empty()) render_row(meshes, F, {}, 160, 400).save_png(png);
}

// The rows of a table a stage wrote (none when it is missing).
std::vector<std::vector<std::string>> read_csv(const fs::path& p) {
  std::vector<std::vector<std::string>> rows;
  std::error_code ec;
  if (!fs::is_regular_file(p, ec)) return rows;
  for (auto& r : read_csv_file(p)) rows.push_back(std::move(r.fields));
  return rows;
}

}  // namespace

namespace {

void add_demo_options(CLI::App* cmd, DemoArgs& a) {
  cmd->add_option("--out", a.out, "Output folder (must not exist unless --force)")->capture_default_str();
  cmd->add_option("--crowd", a.crowd, "Characters in the crowd")->capture_default_str()->check(CLI::Range(1, 100));
  cmd->add_flag("--force", a.force, "Replace an existing output folder");
}

// The demo's fixed choices: which scans it registers, which clips it animates, its sweeps.
const std::vector<std::string> kRegIds = {"s000_p0", "s001_p1"};
const std::vector<std::string> kClips = {"02_02", "03_03", "12_03"};
// Sweeps from the model's mean body ("the typical such person", the likely change): women of 40 at
// 165 cm from 50 to 130 kg (NHANES women's weight p5-p95 is about 50-120 kg) and men of 40 at BMI 25
// from 155 to 195 cm.
const std::vector<int> kHeights = {155, 165, 175, 185, 195};
const std::vector<int> kWeights = {50, 70, 90, 110, 130};
// The crowd's clip frames: a short clip keeps the dressed crowd's cost small (the penetration is
// measured on every frame; docs/results.md#demo-tests-and-ci).
const int kCrowdFrames = 60;

// The dense-marker stage (issue 38) on a short clip: the first meshes of the Vlasic crane capture
// (15 fps), simulated at 120 Hz (23 mesh intervals: 185 capture frames), cleaned against the
// simulation's truth, and a skin driven by the cleaned markers; its meshes written at every mesh
// frame (every 8 capture frames) so the report can show a held-out one beside the truth.
const int kMarkerMeshes = 24, kMarkerMeshRate = 15, kMarkerRate = 120;
const char* const kMarkerDeformStage = "markers: skin from the cleaned markers";
const char* const kMarkerCleanStage = "markers: clean the capture";

std::vector<fs::path> marker_meshes() {
  std::vector<fs::path> files;
  const fs::path dir = data_file("animations") / "vlasic-crane";
  for (int m = 0; m < kMarkerMeshes; ++m) files.push_back(dir / fmt::format("mesh_{:04d}.obj", 2 * m));
  return files;
}

std::string crowd_stage_name(int crowd) { return fmt::format("crowd of {} dressed characters", crowd); }

struct Stage {
  std::string name;
  std::vector<std::string> args;
  std::vector<std::string> needs;  // stage names whose success this one needs
};

// The viewer stage (an offline three.js page) when three.js is installed (scripts/setup.sh): the
// character playing clip 12_03 with its MWE rig and SSD base; to orbit, a registration coloured by
// its distance to the true body (the registration picture's 30 mm scale), the sweeps' ends and the
// crowd.
Stage viewer_stage(const std::function<std::string(const fs::path&)>& p, const fs::path& cmu, int crowd) {
  std::vector<std::string> args = {"viewer", "--rig", p("character/rig.npz"), "--bvh", (cmu / "12_03.bvh").string(),
                                   "--frames", "60", "--every", "2", "--error-mesh", p("reg/" + kRegIds[0] + ".ply"),
                                   p("db/truth/" + kRegIds[0] + ".ply"), "--error-scale", "30"};
  for (const char* s : {"height_155", "height_195", "weight_50", "weight_130"})
    args.insert(args.end(), {"--mesh", p(fmt::format("sweeps/{}.obj", s))});
  for (int i = 0; i < crowd; ++i) args.insert(args.end(), {"--mesh", p(fmt::format("crowd/char_{:03d}/body.obj", i))});
  args.insert(args.end(), {"--no-check", "--out", p("viewer"), "--force"});
  return {"interactive viewer", args,
          {"character (MWE rig)", "register scan " + kRegIds[0], "height sweep 155 cm", "height sweep 195 cm",
           "weight sweep 50 kg", "weight sweep 130 kg", crowd_stage_name(crowd)}};
}

// simulate → clean → deform on the crane clip, when the shared data has it (else a warning).
void add_marker_stages(const std::function<std::string(const fs::path&)>& p, std::vector<Stage>& stages) {
  const std::vector<fs::path> meshes = marker_meshes();
  for (const fs::path& m : meshes)
    if (!fs::is_regular_file(m)) {
      cli::warn("'" + m.string() + "' not found: the report gets no dense-marker capture");
      return;
    }
  std::vector<std::string> sim = {"markers", "simulate"}, deform = {"markers", "deform", p("markers/clean.trc"), "--meshes"};
  for (const fs::path& m : meshes) sim.push_back(m.string()), deform.push_back(m.string());
  const std::string mesh_rate = std::to_string(kMarkerMeshRate);
  sim.insert(sim.end(), {"--mesh-rate", mesh_rate, "--rate", std::to_string(kMarkerRate), "--out", p("markers/sim")});
  stages.push_back({"markers: simulate a capture", sim, {}});
  stages.push_back({kMarkerCleanStage,
                    {"markers", "clean", p("markers/sim/capture.c3d"), "--out", p("markers/clean.trc"), "--truth",
                     p("markers/sim/truth.trc")},
                    {"markers: simulate a capture"}});
  deform.insert(deform.end(), {"--mesh-rate", mesh_rate, "--write-every", std::to_string(kMarkerRate / kMarkerMeshRate),
                               "--out", p("markers/deform")});
  stages.push_back({kMarkerDeformStage, deform, {kMarkerCleanStage}});
}

std::vector<Stage> demo_stages(const fs::path& out, int crowd, bool viewer) {
  const fs::path cmu = data_file("makehuman") / "motion" / "cmu";
  const std::function<std::string(const fs::path&)> p = [&](const fs::path& x) { return (out / x).string(); };
  std::vector<Stage> stages;
  // The subjects are NHANES adults drawn by survey weight, each body fitted to the person's
  // recorded measurements (synth-db --population): a model of real-looking people. Without the
  // survey file the uniform MakeHuman sliders (BMI 15-25, not real adults) with a warning.
  std::vector<std::string> db_args = {"synth-db", "--subjects", "24", "--poses-per-subject", "2", "--seed", "1",
                                      "--out", p("db"), "--force"};
  const fs::path population = data_file("anthropometry") / "nhanes_2017_2020_bmx_demo.csv";
  if (fs::is_regular_file(population)) {
    db_args.insert(db_args.begin() + 1, {"--population", population.string()});
  } else {
    cli::warn("population file not found at " + population.string() +
              ": the demo's subjects are uniform MakeHuman sliders, not real adults");
  }
  stages.push_back({"synthetic scan database", db_args, {}});
  for (auto& id : kRegIds)
    stages.push_back({"register scan " + id, {"register", p("db"), "--out", p("reg"), "--scan", id, "--jobs", "1"},
                      {"synthetic scan database"}});
  stages.push_back({"evaluate registration", {"eval-registration", p("db"), p("reg"), "--csv", p("registration.csv")},
                    {"register scan " + kRegIds[0]}});
  stages.push_back({"build model", {"build", p("db/truth"), "--db", p("db"), "--out", p("model.npz")},
                    {"synthetic scan database"}});
  stages.push_back({"regressor table", {"eval-regressors", p("model.npz"), "--folds", "6", "--out", p("regressors")},
                    {"build model"}});
  for (int h : kHeights)
    stages.push_back({fmt::format("height sweep {} cm", h),
                      {"morph", p("model.npz"), "--set", "sex=male", "--set", "age_years=40", "--set",
                       fmt::format("height_cm={}", h), "--set", fmt::format("weight_kg={:.1f}", 25.0 * h * h / 1e4),
                       "--closest", "--out", p(fmt::format("sweeps/height_{}.obj", h))},
                      {"build model"}});
  for (int w : kWeights)
    stages.push_back({fmt::format("weight sweep {} kg", w),
                      {"morph", p("model.npz"), "--set", "sex=female", "--set", "age_years=40", "--set", "height_cm=165",
                       "--set", fmt::format("weight_kg={}", w), "--closest", "--out",
                       p(fmt::format("sweeps/weight_{}.obj", w))},
                      {"build model"}});
  // Dressed by the default outfits with levels of detail: crowd.html, the crowd viewer, beside them.
  stages.push_back({crowd_stage_name(crowd),
                    {"crowd", p("model.npz"), "--count", std::to_string(crowd), "--quick", "--bvh",
                     (cmu / "12_03.bvh").string(), "--max-frames", std::to_string(kCrowdFrames), "--seed", "5",
                     "--outfits", "default", "--lods", "default", "--out", p("crowd")},
                    {"build model"}});
  stages.push_back({"character (MWE rig)", {"character", p("model.npz"), "--where", "sex=male", "--where",
                                           "height_cm=185", "--seed", "3", "--out", p("character")},
                    {"build model"}});
  for (auto& c : kClips)
    stages.push_back({"animate " + c, {"animate", p("character/rig.npz"), "--bvh", (cmu / (c + ".bvh")).string(),
                                       "--out", p("animation/" + c), "--format", "none"},
                      {"character (MWE rig)"}});
  add_marker_stages(p, stages);
  if (viewer) {
    Stage v = viewer_stage(p, cmu, crowd);
    // The cleaned markers playing, the filled samples in the filled colour.
    if (std::any_of(stages.begin(), stages.end(), [](const Stage& s) { return s.name == kMarkerCleanStage; })) {
      v.args.insert(v.args.end(), {"--markers", p("markers/clean.trc"), "--marker-report", p("markers/clean.json")});
      v.needs.push_back(kMarkerCleanStage);
    }
    stages.push_back(v);
  }
  return stages;
}

// Runs the stages in order, skipping those whose needs failed; status: exit code per stage name.
std::vector<StageResult> run_stages(const std::vector<Stage>& stages, const fs::path& out,
                                    std::map<std::string, int>& status) {
  std::vector<StageResult> results;
  const int total = static_cast<int>(stages.size()) + 1;
  for (size_t i = 0; i < stages.size(); ++i) {
    const Stage& s = stages[i];
    bool ok = true;
    for (auto& n : s.needs) ok = ok && status.count(n) && status[n] == 0;
    if (!ok) {
      fmt::print(stderr, "[{:2d}/{}] {:<34}     -  skipped (an earlier stage failed)\n", int(i + 1), total, s.name);
      results.push_back({s.name, 0, -1, ""});
      status[s.name] = -1;
      continue;
    }
    std::string logname = s.name;
    for (char& c : logname)
      if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
    StageResult r = run_stage(int(i + 1), total, s.name, s.args, out / "logs" / (logname + ".log"));
    status[s.name] = r.exit_code;
    results.push_back(r);
  }
  return results;
}

// The dressed crowd's pictures (line-up, levels of detail, close-up); nothing when it failed.
std::optional<DressedCrowdPictures> dressed_pictures(const fs::path& out, int crowd) {
  try {
    DressedCrowdPictures d = dressed_crowd_pictures(out / "crowd", crowd);
    save_dressed_crowd_pictures(d, out / "pictures");
    return d;
  } catch (const std::exception& e) {
    cli::warn(std::string("dressed crowd pictures: ") + e.what());
    return std::nullopt;
  }
}

// The marker stage's pictures and table; nothing when it failed.
std::optional<MarkerPictures> demo_marker_pictures(const fs::path& out) {
  try {
    MarkerPictures m = marker_pictures(out / "markers", marker_meshes(), kMarkerRate / kMarkerMeshRate, 1000);
    save_marker_pictures(m, out / "pictures");
    write_text_file(out / "markers" / "markers.csv", marker_summary_csv(out / "markers"));
    return m;
  } catch (const std::exception& e) {
    cli::warn(std::string("marker pictures: ") + e.what());
    return std::nullopt;
  }
}

void demo_pictures(const fs::path& out) {
  const fs::path pic = out / "pictures";
  try {
    registration_pictures(out, kRegIds, 30);
    std::vector<fs::path> hs, ws;
    for (int h : kHeights) hs.push_back(out / "sweeps" / fmt::format("height_{}.obj", h));
    for (int w : kWeights) ws.push_back(out / "sweeps" / fmt::format("weight_{}.obj", w));
    row_picture(hs, pic / "height_sweep.png");
    row_picture(ws, pic / "weight_sweep.png");
  } catch (const std::exception& e) {
    cli::warn(std::string("pictures: ") + e.what());
  }
}

// The animation table from the clips' per-frame checks.
std::string animation_table(const fs::path& out) {
  std::string anim_csv =
      "clip,frames,rig_max_edge_ratio,ssd_max_edge_ratio,template_max_edge_ratio,rig_max_flipped,template_max_flipped,"
      "rig_max_p99_edge_ratio,rig_worst_bone\n";
  for (auto& c : kClips) {
    auto rows = read_csv(out / "animation" / c / "animation.csv");
    if (rows.size() < 2) continue;
    double r = 0, l = 0, t = 0, p99 = 0;
    int fr = 0, ft = 0;
    std::string where;
    for (size_t k = 1; k < rows.size(); ++k) {
      if (rows[k].size() < 10) continue;
      if (rows[k].size() >= 15) {
        p99 = std::max(p99, std::stod(rows[k][10]));
        if (std::stod(rows[k][3]) > r) where = rows[k][14];
      }
      r = std::max(r, std::stod(rows[k][3]));
      fr = std::max(fr, std::stoi(rows[k][5]));
      l = std::max(l, std::stod(rows[k][6]));
      t = std::max(t, std::stod(rows[k][8]));
      ft = std::max(ft, std::stoi(rows[k][9]));
    }
    anim_csv += fmt::format("{},{},{:.3f},{:.3f},{:.3f},{},{},{:.3f},{}\n", c, rows.size() - 1, r, l, t, fr, ft, p99, where);
  }
  return anim_csv;
}

std::string timings_table(const std::vector<StageResult>& results, const fs::path& out, double report_seconds,
                          double total_seconds, int& failed) {
  std::string tim = "stage,seconds,status,log\n";
  failed = 0;
  for (auto& r : results) {
    failed += r.exit_code != 0;
    tim += fmt::format("{},{:.1f},{},{}\n", r.name, r.seconds,
                       r.exit_code == 0 ? "ok" : r.exit_code < 0 ? "skipped" : fmt::format("failed (exit {})", r.exit_code),
                       r.log.empty() ? "" : fs::relative(r.log, out).string());
  }
  tim += fmt::format("pictures and report,{:.1f},ok,\ntotal,{:.1f},{},\n", report_seconds, total_seconds,
                     failed ? fmt::format("{} stages failed or skipped", failed) : "ok");
  return tim;
}

// Section 4: the crowd, bare and dressed, and the link to its viewer.
std::string crowd_section(const fs::path& out, const std::optional<DressedCrowdPictures>& dressed) {
  std::string b = "<h2>4. A crowd of rigged, animated, dressed characters</h2>\n";
  b += html_figure(out / "crowd" / "crowd.png", "crowd/crowd.png", "The generated crowd's bodies (rest pose).");
  b += html_table_from_csv(out / "crowd" / "crowd.csv", "crowd/crowd.csv");
  b += "<p>Each character folder holds <code>character.glb</code> (SSD rig) and <code>anim/animated.glb</code> "
       "(with the clip), viewable in any glTF viewer.</p>\n";
  if (dressed) b += dressed_crowd_html(out, *dressed);
  return b;
}

std::string report_body(const fs::path& out, double total_seconds, bool viewer_ok,
                        const std::optional<DressedCrowdPictures>& dressed, const std::optional<MarkerPictures>& markers) {
  const fs::path pic = out / "pictures";
  std::string b;
  b += "<p>The whole pipeline on the bundled MakeHuman data, made by <code>bodymodel demo</code> in " +
       fmt::format("{:.0f}", total_seconds) + " s. Every number comes from the CSV linked under its table; the "
       "logs of every stage are in <a href=\"logs/\">logs/</a>.</p>\n";
  b += "<h2>1. Registration (synthetic scans, ground truth known)</h2>\n";
  b += html_figure(pic / "registration_error.png", "pictures/registration_error.png",
                   "Correspondence error of the registered template against the true body, per vertex "
                   "(scans " + kRegIds[0] + ", " + kRegIds[1] + "), blue 0 → red ≥ 30 mm.");
  b += html_table_from_csv(out / "registration.csv", "registration.csv");
  b += "<h2>2. Semantic morphs</h2>\n";
  b += "<div class=\"pair\">\n";
  b += html_figure(pic / "height_sweep.png", "pictures/height_sweep.png",
                   "Height sweep 155, 165, 175, 185, 195 cm at BMI 25: men of 40, the model's typical body "
                   "for each (morph from the mean).");
  b += html_figure(pic / "weight_sweep.png", "pictures/weight_sweep.png",
                   "Weight sweep 50, 70, 90, 110, 130 kg at 165 cm: women of 40, the model's typical body for "
                   "each (morph from the mean).");
  b += "</div>\n";
  b += "<h2>3. Regressors (cross-validated RMSE)</h2>\n";
  b += html_table_from_csv(out / "regressors" / "regressors.csv", "regressors/regressors.csv");
  b += crowd_section(out, dressed);
  b += "<h2>5. Skinning: SSD vs Animation Space vs MWE on the character</h2>\n";
  b += html_figure(out / "character" / "skinning_error.png", "character/skinning_error.png",
                   "Held-out pose with the largest SSD error: the model's pose morph (grey), then SSD, Animation "
                   "Space and MWE coloured by vertex error, fixed scale blue 0 → red ≥ 60 mm.");
  b += html_table_from_csv(out / "character" / "fit.csv", "character/fit.csv");
  b += "<p>Vertex error (mm) against the model's own pose morphs; <code>template_lbs</code> = MakeHuman's "
       "weights as they are, <code>smooth_lbs</code> = the same smoothed (the SSD that Animation Space and MWE "
       "refine, and the glb's), <code>lbs</code> = SSD weights fitted to the training poses.</p>\n";
  b += "<h2>6. Animation (CMU clips retargeted to the template skeleton)</h2>\n";
  for (auto& c : kClips)
    b += html_figure(out / "animation" / c / "frames.png", "animation/" + c + "/frames.png",
                     "Clip " + c + ": six frames of the MWE-skinned character.");
  b += html_table_from_csv(out / "animation.csv", "animation.csv");
  if (viewer_ok)
    b += "<p><b><a href=\"viewer/index.html\">Interactive 3D viewer</a></b> (opens from the file system, no "
         "network): the character playing clip 12_03, skinned in a WebGL vertex shader with its MWE rig or its SSD "
         "base, the per-vertex distance between them; to orbit, the registered scan coloured by its distance to the "
         "true body, the sweeps' ends and the crowd (one by one or side by side)" +
         std::string(markers ? "; the cleaned markers of section 7 playing, the filled samples in orange" : "") + ".</p>\n";
  b += "<p>Largest edge-length ratio to rest over all frames (the issue's check: at most 3), its largest "
       "99th percentile over edges, the main bone at the worst edge, and flipped triangles (normal against the "
       "rotation of the triangle's main bone), for the MWE rig, its SSD base (MakeHuman's weights smoothed) and "
       "the template weights as they are.</p>\n";
  if (markers) {
    b += "<h2>7. Dense-marker capture (Park &amp; Hodgins)</h2>\n<p>About 350 markers simulated on the first " +
         std::to_string(kMarkerMeshes) + " meshes of the Vlasic crane capture (cameras, gaps, noise, broken and ghost "
         "trajectories: <code>markers simulate</code>), cleaned (<code>markers clean</code>) and driving the first mesh "
         "(<code>markers deform</code>; even meshes train, odd ones are held out).</p>\n";
    b += marker_pictures_html(out, *markers);
  }
  b += fmt::format("<h2>{}. Timings</h2>\n", markers ? 8 : 7) + html_table_from_csv(out / "timings.csv", "timings.csv", 100);
  return b;
}

void print_demo_summary(const std::vector<StageResult>& results, const fs::path& out, double total_seconds) {
  fmt::print("\n{:<36} {:>8}  {}\n", "stage", "seconds", "status");
  for (auto& r : results)
    fmt::print("{:<36} {:>8.1f}  {}\n", r.name, r.seconds,
               r.exit_code == 0 ? "ok" : r.exit_code < 0 ? "skipped" : "FAILED, see " + r.log);
  fmt::print("{:<36} {:>8.1f}\n", "total", total_seconds);
  auto fit = read_csv(out / "character" / "fit.csv");
  for (auto& row : fit)
    if (row.size() >= 5 && row[1] == "held_out" && (row[0] == "lbs" || row[0] == "mwe"))
      fmt::print("character held-out vertex error {:<4} mean {} mm, max {} mm\n", row[0], row[3], row[4]);
  fmt::print("report: {}\n", (out / "report.html").string());
}

void run_demo(DemoArgs& a) {
  const fs::path out = fs::path(a.out).filename().empty() ? fs::path(a.out).parent_path() : fs::path(a.out);
  std::error_code ec;
  refuse_existing_output(out, a.force);
  if (fs::exists(out, ec)) {
    fs::remove_all(out, ec);
    if (ec) throw InputError("cannot remove '" + out.string() + "': " + ec.message());
  }
  for (const char* d : {"", "logs", "pictures", "sweeps", "animation", "markers"}) ensure_directory(out / d);
  const bool viewer = fs::is_regular_file(cli::default_three_js());
  if (!viewer)
    cli::warn("three.js not found at " + cli::default_three_js().string() + ": the report gets no interactive viewer");
  const std::vector<Stage> stages = demo_stages(out, a.crowd, viewer);

  auto t0 = std::chrono::steady_clock::now();
  std::map<std::string, int> status;
  const std::vector<StageResult> results = run_stages(stages, out, status);
  // Pictures and the report (in this process).
  auto tr = std::chrono::steady_clock::now();
  const int total = static_cast<int>(stages.size()) + 1;
  fmt::print(stderr, "[{:2d}/{}] {:<34} ...\n", total, total, "pictures and report");
  demo_pictures(out);
  const std::optional<DressedCrowdPictures> dressed =
      status[crowd_stage_name(a.crowd)] == 0 ? dressed_pictures(out, a.crowd) : std::nullopt;
  const std::optional<MarkerPictures> markers =
      status.count(kMarkerDeformStage) && status[kMarkerDeformStage] == 0 ? demo_marker_pictures(out) : std::nullopt;
  write_text_file(out / "animation.csv", animation_table(out));
  const double report_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tr).count();
  const double total_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  int failed = 0;
  write_text_file(out / "timings.csv", timings_table(results, out, report_seconds, total_seconds, failed));
  const std::string body = report_body(out, total_seconds, viewer && status["interactive viewer"] == 0, dressed, markers);
  write_text_file(out / "report.html", html_page("bodymodel: scans to animated characters", body));
  print_demo_summary(results, out, total_seconds);
  if (failed) throw InputError(fmt::format("demo: {} stages failed or were skipped (see {})", failed,
                                           (out / "timings.csv").string()));
}

}  // namespace

BODYMODEL_VERB(add_demo_verb) {
  auto a = std::make_shared<DemoArgs>();
  auto* cmd = app.add_subcommand(
      "demo",
      "The whole pipeline on the bundled data: synthetic scan database → registration of two scans\n"
      "+ evaluation → model → regressor table → height and weight sweeps → a crowd of rigged,\n"
      "animated, dressed characters → one character animated with every CMU clip → a dense-marker\n"
      "capture simulated, cleaned and driving a skin (a short Vlasic crane clip) → OUT/report.html.\n"
      "Each stage runs as a subprocess (log in OUT/logs/); a failed stage is reported and the\n"
      "stages that need its output are skipped.");
  add_demo_options(cmd, *a);
  cmd->callback([a] { run_demo(*a); });
}

}  // namespace bodymodel
