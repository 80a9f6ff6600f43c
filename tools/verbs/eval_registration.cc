// bodymodel eval-registration DB/ REG/ [--csv FILE] [--per-joint] [--flipped-regions]
//                             [--flipped-csv FILE] [--hole-csv FILE]
//
// Compares registered meshes and poses with the database's ground truth
// (docs/evaluation.md#registration-against-ground-truth): correspondence error (per-scan mean,
// median over scans, 95th percentile of all vertices), surface fit, hole error, flipped triangles
// and joint rotation error.
#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <filesystem>
#include <map>
#include <sstream>

#include "core/error.h"
#include "core/geometry.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/mesh_io.h"
#include "core/io/pose_csv.h"
#include "core/makehuman.h"
#include "core/rotation.h"
#include "model/database.h"
#include "registration/evaluation.h"
#include "tools/console.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct EvalArgs {
  std::string db, reg, csv, flipped_csv, hole_csv;
  bool per_joint = false, flipped_regions = false;
};

constexpr const char* kEvaluationHeader =
    "scan_id,correspondence_mean_mm,correspondence_p95_mm,correspondence_max_mm,"
    "surface_mean_mm,surface_max_mm,hole_vertices,hole_mean_mm,hole_max_mm,"
    "flipped_triangles,joint_median_deg,joint_max_deg,finger_median_deg,flipped_hands,"
    "flipped_where_truth_folded,folded_in_registration,flipped_unseen\n";

std::string evaluation_row(const std::string& id, const ScanEvaluation& s) {
  const RegistrationErrors& e = s.errors;
  return fmt::format("{},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},{},{:.3f},{:.3f},{},{:.3f},{:.3f},{:.3f},{},{},{},{}\n",
                     csv_field(id), e.correspondence_mean, s.correspondence_p95, e.correspondence_max, e.surface_mean,
                     e.surface_max, e.hole_vertices, e.hole_mean, e.hole_max, e.flipped_triangles, s.joint_median,
                     s.joint_max, s.finger_median, s.flipped_hands, s.flipped_truth_folded, s.folded_registration,
                     e.flipped_unseen);
}

std::string flipped_rows(const std::string& id, const ScanEvaluation& s, const Skeleton& sk) {
  std::string rows;
  for (const FlippedTriangle& t : s.flipped)
    rows += fmt::format("{},{},{},{},{:.1f},{:.3f},{:.3f},{},{},{:.1f},{:.1f},{:.1f}\n", csv_field(id), t.triangle, t.region,
                        sk.names[t.bone], t.angle_deg, t.truth_area_ratio, t.registered_area_ratio, int(t.unseen),
                        int(t.truth_folded), t.centroid.x(), t.centroid.y(), t.centroid.z());
  return rows;
}

std::string hole_rows(const std::string& id, const ScanEvaluation& s, const Skeleton& sk) {
  std::string rows;
  for (const HoleVertex& h : s.holes)
    rows += fmt::format("{},{},{},{},{:.2f},{:.2f}\n", csv_field(id), h.vertex, h.region, sk.names[h.bone], h.surface_mm,
                        h.correspondence_mm);
  return rows;
}

void print_summary(const RegistrationEvaluationSummary& t, bool per_joint, bool flipped_regions) {
  fmt::print("registration vs truth, {} scans\n", t.scans);
  fmt::print("  correspondence error   median of per-scan means {:8.3f} mm   (target <= 5)\n",
             t.correspondence_median_of_means);
  fmt::print("                         95th percentile, all vertices {:8.3f} mm   (target <= 15)\n",
             t.correspondence_p95_all);
  fmt::print("  surface fit            mean over scans {:8.3f} mm   (target <= 1.5)\n", t.surface_mean);
  fmt::print("  hole error             max inside holes {:8.3f} mm, median of per-scan max "
             "{:.3f} mm   (target <= 20)\n",
             t.hole_max, t.hole_median_of_max);
  fmt::print("  flipped triangles      {} in total (target 0)\n", t.flipped);
  fmt::print("    of which the truth itself is folded there   {}   (linear blend skinning collapsed "
             "a crease of the synthetic body: triangle against its 2-ring, unlike at rest)\n",
             t.flipped_truth_folded);
  fmt::print("    of which the scanner did not see them       {}   (all three vertices' true "
             "positions > 5 mm from every scan point)\n",
             t.flipped_unseen);
  fmt::print("    seen, where the truth is not folded         {}\n", t.flipped_seen_unfolded);
  fmt::print("  locally folded         {} in the registrations, {} in the truths   (triangle "
             "against its 2-ring, unlike at rest: needs no truth)\n",
             t.folded_registration, t.folded_truth);
  if (t.joint_samples)
    fmt::print("  joint rotation error   median {:6.3f} deg, 95th percentile {:6.3f} deg over "
               "{} major joints × scans   (target median <= 5)\n",
               t.joint_median, t.joint_p95, t.joint_samples);
  if (flipped_regions)
    for (const auto& [region, count] : t.flipped_by_region)
      fmt::print("    flipped in {:<14} {:5}   ({} unseen)\n", region, count,
                 t.flipped_unseen_by_region.count(region) ? t.flipped_unseen_by_region.at(region) : 0);
  if (per_joint && t.joint_samples)
    for (size_t j = 0; j < t.joint_names.size(); ++j)
      fmt::print("    {:<14} median {:6.2f} deg, max {:6.2f} deg   (swing median {:6.2f}, "
                 "twist median {:6.2f})\n",
                 t.joint_names[j], t.joint_medians[j], t.joint_maxima[j], t.swing_medians[j], t.twist_medians[j]);
  if (per_joint && !std::isnan(t.finger_median))
    fmt::print("    distal phalanges (not major joints) median {:6.2f} deg, 95th percentile "
               "{:6.2f} deg\n",
               t.finger_median, t.finger_p95);
}

}  // namespace

BODYMODEL_VERB(add_eval_registration_verb) {
  auto a = std::make_shared<EvalArgs>();
  auto* cmd = app.add_subcommand(
      "eval-registration",
      "Compare registrations (REG/<id>.ply, <id>.pose.csv) with the database's ground truth\n"
      "(DB/truth/): correspondence, surface-fit, hole and joint errors (docs/evaluation.md).\n"
      "Writes REG/evaluation.csv (per scan) unless --csv says otherwise; prints a summary.");
  cmd->add_option("db", a->db, "Scan database folder (with truth/)")->required();
  cmd->add_option("reg", a->reg, "Registration folder written by 'bodymodel register'")
      ->required();
  cmd->add_option("--csv", a->csv, "Per-scan CSV to write (default REG/evaluation.csv)");
  cmd->add_flag("--per-joint", a->per_joint, "Also print the median error of each major joint");
  cmd->add_flag("--flipped-regions", a->flipped_regions,
                "Also print where the flipped triangles are (body region of the bone with the "
                "largest weight at the triangle's vertices)");
  cmd->add_option("--flipped-csv", a->flipped_csv,
                  "Also write every flipped triangle (scan, triangle, region, bone, angle between "
                  "its normal and the truth's, areas against rest, unseen, truth folded, centroid)");
  cmd->add_option("--hole-csv", a->hole_csv,
                  "Also write every hole vertex more than 10 mm from the true surface (scan, "
                  "vertex, region, bone, distance, correspondence error)");
  cmd->callback([a] {
    const fs::path db = a->db, reg = a->reg;
    if (!fs::is_directory(db / "truth"))
      throw InputError("'" + a->db + "': expected a scan database with a truth/ folder");
    if (!fs::is_directory(reg))
      throw InputError("'" + a->reg + "': expected a registration folder, it does not exist");
    std::vector<std::string> ids;
    for (const ScanTableRow& row : read_scan_table(db / "scans.csv")) ids.push_back(row.scan_id);
    MakeHuman::Body body = MakeHuman::load().body(MacroSettings{});
    RegistrationEvaluator evaluator(body.mesh, body.skeleton, body.weights);
    const Skeleton& sk = evaluator.skeleton();
    std::string csv = kEvaluationHeader;
    std::string flipped =
        "scan_id,triangle,region,bone,angle_deg,truth_area_ratio,registered_area_ratio,unseen,"
        "truth_folded,x,y,z\n";
    std::string holes = "scan_id,vertex,region,bone,surface_mm,correspondence_mm\n";
    int missing = 0;
    cli::ProgressBar bar("eval-registration");
    for (size_t k = 0; k < ids.size(); ++k) {
      const std::string& id = ids[k];
      bar.update(double(k) / ids.size(), id);
      if (!fs::exists(reg / (id + ".ply"))) {
        ++missing;
        continue;
      }
      const Mesh r = read_mesh(reg / (id + ".ply"));
      const Mesh t = read_mesh(db / "truth" / (id + ".ply"));
      if (r.V.rows() != t.V.rows())
        throw InputError((reg / (id + ".ply")).string() + ": " + std::to_string(r.V.rows()) +
                         " vertices, the truth has " + std::to_string(t.V.rows()));
      const PointCloud scan = read_point_cloud(db / "scans" / (id + ".ply"));
      std::optional<PoseRecord> reg_pose, truth_pose;
      if (fs::exists(reg / (id + ".pose.csv")) && fs::exists(db / "truth" / (id + ".pose.csv"))) {
        reg_pose = read_pose_csv(reg / (id + ".pose.csv"), sk.names);
        truth_pose = read_pose_csv(db / "truth" / (id + ".pose.csv"), sk.names);
      }
      const ScanEvaluation e = evaluator.evaluate_scan(r.V, t.V, scan.P, reg_pose ? &*reg_pose : nullptr,
                                                       truth_pose ? &*truth_pose : nullptr);
      evaluator.add(e);
      csv += evaluation_row(id, e);
      if (!a->flipped_csv.empty()) flipped += flipped_rows(id, e, sk);
      if (!a->hole_csv.empty()) holes += hole_rows(id, e, sk);
    }
    const RegistrationEvaluationSummary summary = evaluator.summary();
    bar.finish(fmt::format("{} scans evaluated", summary.scans));
    if (summary.scans == 0)
      throw InputError("'" + a->reg + "': no registered scans of " + a->db + " found");
    if (missing) cli::warn(fmt::format("{} scans of the database have no registration", missing));
    write_text_file(a->csv.empty() ? reg / "evaluation.csv" : fs::path(a->csv), csv);
    if (!a->flipped_csv.empty()) write_text_file(a->flipped_csv, flipped);
    if (!a->hole_csv.empty()) write_text_file(a->hole_csv, holes);
    print_summary(summary, a->per_joint, a->flipped_regions);
  });
}

}  // namespace bodymodel
