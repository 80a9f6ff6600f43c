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
#include "core/io/file_names.h"
#include "core/io/mesh_io.h"
#include "core/io/pose_csv.h"
#include "core/makehuman.h"
#include "core/rotation.h"
#include "registration/metrics.h"
#include "tools/console.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct EvalArgs {
  std::string db, reg, csv, flipped_csv, hole_csv;
  bool per_joint = false, flipped_regions = false;
};

// Body region of a MakeHuman bone name, for the flipped-triangle breakdown.
std::string bone_region(const std::string& b) {
  auto has = [&](const char* k) { return b.find(k) != std::string::npos; };
  if (has("finger") || has("metacarpal") || has("wrist")) return "hands";
  if (has("toe") || has("foot")) return "feet";
  if (has("head") || has("jaw") || has("eye") || has("tongue") || has("teeth") || has("ear") ||
      has("lip") || has("nose") || has("cheek") || has("brow") || has("temple") || has("chin") ||
      has("levator") || has("oris") || has("oculi") || has("risorius") || has("special"))
    return "head/face";
  if (has("neck")) return "neck";
  if (has("upperleg") || has("lowerleg")) return "legs";
  if (has("upperarm") || has("lowerarm")) return "arms";
  if (has("clavicle") || has("shoulder")) return "shoulders";
  return "torso/pelvis";
}

// Swing (angle between the bone's posed directions) and twist (rotation about the bone's own
// axis that is left) of the error between two world rotations of a bone with rest direction d.
std::pair<double, double> swing_twist_deg(const Eigen::Matrix3d& Qe, const Eigen::Matrix3d& Qt,
                                          const Eigen::Vector3d& d) {
  const Eigen::Quaterniond q(Qt.transpose() * Qe);  // error in the bone's rest frame
  const Eigen::Vector3d e = q * d;
  const double swing = std::acos(std::clamp(e.dot(d), -1.0, 1.0)) * 180.0 / M_PI;
  double twist = 2.0 * std::atan2(q.vec().dot(d), q.w()) * 180.0 / M_PI;
  if (twist > 180) twist -= 360;
  if (twist < -180) twist += 360;
  return {swing, std::abs(twist)};
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double pos = q * (v.size() - 1);
  const size_t lo = size_t(pos), hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - lo) * (v[hi] - v[lo]);
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
    {
      const std::vector<CsvRecord> rows = read_csv_file(db / "scans.csv");
      for (size_t r = 1; r < rows.size(); ++r) {
        ids.push_back(rows[r].fields[0]);
        // The id names files read from DB/truth/ and REG/: one plain name.
        check_file_name(ids.back(), (db / "scans.csv").string() + ":" + std::to_string(rows[r].line), "scan id");
      }
    }
    MakeHuman mh = MakeHuman::load();
    MakeHuman::Body body = mh.body(MacroSettings{});
    const Skeleton& sk = body.skeleton;
    std::vector<int> joints;
    for (const auto& n : major_joints())
      if (sk.find(n) >= 0) joints.push_back(sk.find(n));

    std::string csv =
        "scan_id,correspondence_mean_mm,correspondence_p95_mm,correspondence_max_mm,"
        "surface_mean_mm,surface_max_mm,hole_vertices,hole_mean_mm,hole_max_mm,"
        "flipped_triangles,joint_median_deg,joint_max_deg,finger_median_deg,flipped_hands,"
        "flipped_where_truth_folded,folded_in_registration,flipped_unseen\n";
    std::vector<double> scan_means, all_vertices, surface_means, hole_max, joint_all;
    std::vector<double> scan_joint_medians;
    std::vector<std::vector<double>> per_joint(joints.size()), per_swing(joints.size()),
        per_twist(joints.size());
    std::vector<Eigen::Vector3d> rest_dir(sk.bone_count(), Eigen::Vector3d::UnitY());
    for (int b = 0; b < sk.bone_count(); ++b) {
      const Eigen::Vector3d d = (sk.tails.row(b) - sk.heads.row(b)).transpose();
      if (d.norm() > 1e-9) rest_dir[b] = d.normalized();
    }
    // Distal phalanx of each finger (evaluated apart: not a major joint).
    std::vector<int> fingertips;
    for (const char* side : {".L", ".R"})
      for (int f = 1; f <= 5; ++f)
        if (sk.find("finger" + std::to_string(f) + "-3" + side) >= 0)
          fingertips.push_back(sk.find("finger" + std::to_string(f) + "-3" + side));
    std::vector<double> finger_all;
    int flipped_total = 0, evaluated = 0, missing = 0;
    int flipped_truth_folded_total = 0, folded_registration_total = 0, folded_truth_total = 0;
    int flipped_unseen_total = 0, flipped_seen_unfolded_total = 0;
    std::map<std::string, int> flipped_by_region, flipped_unseen_by_region;
    std::vector<std::string> vertex_region;  // always: the per-scan flipped_hands column
    std::vector<int> vertex_bone;              // bone with the largest weight at each vertex
    std::string flipped_rows =
        "scan_id,triangle,region,bone,angle_deg,truth_area_ratio,registered_area_ratio,unseen,"
        "truth_folded,x,y,z\n";
    std::string hole_rows = "scan_id,vertex,region,bone,surface_mm,correspondence_mm\n";
    const Eigen::VectorXd rest_area = face_areas(body.mesh.V, body.mesh.F);
    {
      const SkinWeights& W = body.weights;
      vertex_region.assign(W.rows(), "torso/pelvis");
      vertex_bone.assign(W.rows(), 0);
      for (int i = 0; i < W.outerSize(); ++i) {
        double best = 0;
        for (SkinWeights::InnerIterator it(W, i); it; ++it)
          if (it.value() > best) {
            best = it.value();
            vertex_region[i] = bone_region(sk.names[it.col()]);
            vertex_bone[i] = int(it.col());
          }
      }
    }
    double worst_hole = 0;
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
      const RegistrationErrors e = registration_errors(r.V, t.V, t.F, scan.P);
      std::vector<double> verr(e.vertex_errors.data(),
                               e.vertex_errors.data() + e.vertex_errors.size());
      all_vertices.insert(all_vertices.end(), verr.begin(), verr.end());
      scan_means.push_back(e.correspondence_mean);
      surface_means.push_back(e.surface_mean);
      hole_max.push_back(e.hole_max);
      worst_hole = std::max(worst_hole, e.hole_max);
      flipped_total += e.flipped_triangles;
      if (!a->hole_csv.empty())
        for (Eigen::Index i = 0; i < t.V.rows(); ++i)
          if (e.hole_vertex[i] && e.surface_errors(i) > 10.0)
            hole_rows += fmt::format("{},{},{},{},{:.2f},{:.2f}\n", csv_field(id), i, vertex_region[i],
                                     sk.names[vertex_bone[i]], e.surface_errors(i),
                                     e.vertex_errors(i));
      int flipped_hands = 0, flipped_truth_folded = 0, folded_registration = 0;
      {
        const Eigen::MatrixX3d Nr = face_normals(r.V, t.F), Nt = face_normals(t.V, t.F);
        const Eigen::VectorXd reg_area = face_areas(r.V, t.F), truth_area = face_areas(t.V, t.F);
        const std::vector<char> truth_folded = locally_folded_triangles(t.V, body.mesh.V, t.F);
        const std::vector<char> reg_folded = locally_folded_triangles(r.V, body.mesh.V, t.F);
        folded_registration = int(std::count(reg_folded.begin(), reg_folded.end(), 1));
        folded_truth_total += int(std::count(truth_folded.begin(), truth_folded.end(), 1));
        for (Eigen::Index f = 0; f < t.F.rows(); ++f)
          if (e.flipped[f]) {
            flipped_truth_folded += truth_folded[f];
            const bool unseen = e.hole_vertex[t.F(f, 0)] && e.hole_vertex[t.F(f, 1)] &&
                                e.hole_vertex[t.F(f, 2)];
            flipped_seen_unfolded_total += !unseen && !truth_folded[f];
            // Region most of the triangle's vertices are in.
            std::map<std::string, int> votes;
            for (int c = 0; c < 3; ++c) ++votes[vertex_region[t.F(f, c)]];
            auto best = std::max_element(votes.begin(), votes.end(),
                                         [](const auto& x, const auto& y) { return x.second < y.second; });
            ++flipped_by_region[best->first];
            flipped_unseen_by_region[best->first] += unseen;
            flipped_hands += best->first == "hands";
            if (!a->flipped_csv.empty()) {
              const Eigen::RowVector3d c =
                  (t.V.row(t.F(f, 0)) + t.V.row(t.F(f, 1)) + t.V.row(t.F(f, 2))) / 3.0;
              const double cosine = std::clamp(Nr.row(f).dot(Nt.row(f)), -1.0, 1.0);
              const double ra = std::max(rest_area(f), 1e-12);
              flipped_rows += fmt::format(
                  "{},{},{},{},{:.1f},{:.3f},{:.3f},{},{},{:.1f},{:.1f},{:.1f}\n", id, f, best->first,
                  sk.names[vertex_bone[t.F(f, 0)]], std::acos(cosine) * 180.0 / M_PI,
                  truth_area(f) / ra, reg_area(f) / ra, int(unseen), int(truth_folded[f]), c.x(),
                  c.y(), c.z());
            }
          }
      }
      double jmed = std::nan(""), jmax = std::nan(""), fmed = std::nan("");
      if (fs::exists(reg / (id + ".pose.csv")) && fs::exists(db / "truth" / (id + ".pose.csv"))) {
        const auto Qe = read_pose_csv(reg / (id + ".pose.csv"), sk.names).world_rotations(sk);
        const auto Qt = read_pose_csv(db / "truth" / (id + ".pose.csv"), sk.names).world_rotations(sk);
        std::vector<double> je;
        for (size_t j = 0; j < joints.size(); ++j) {
          je.push_back(rotation_angle_deg(Qe[joints[j]], Qt[joints[j]]));
          per_joint[j].push_back(je.back());
          const auto [sw, tw] = swing_twist_deg(Qe[joints[j]], Qt[joints[j]], rest_dir[joints[j]]);
          per_swing[j].push_back(sw);
          per_twist[j].push_back(tw);
        }
        std::vector<double> fe;
        for (int b : fingertips) fe.push_back(rotation_angle_deg(Qe[b], Qt[b]));
        finger_all.insert(finger_all.end(), fe.begin(), fe.end());
        fmed = percentile(fe, 0.5);
        joint_all.insert(joint_all.end(), je.begin(), je.end());
        jmed = percentile(je, 0.5);
        jmax = *std::max_element(je.begin(), je.end());
        scan_joint_medians.push_back(jmed);
      }
      flipped_truth_folded_total += flipped_truth_folded;
      flipped_unseen_total += e.flipped_unseen;
      folded_registration_total += folded_registration;
      csv += fmt::format("{},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},{},{:.3f},{:.3f},{},{:.3f},{:.3f},{:.3f},{},{},{},{}\n",
                         csv_field(id), e.correspondence_mean, percentile(verr, 0.95),
                         e.correspondence_max, e.surface_mean, e.surface_max, e.hole_vertices,
                         e.hole_mean, e.hole_max, e.flipped_triangles, jmed, jmax, fmed, flipped_hands,
                         flipped_truth_folded, folded_registration, e.flipped_unseen);
      ++evaluated;
    }
    bar.finish(fmt::format("{} scans evaluated", evaluated));
    if (evaluated == 0)
      throw InputError("'" + a->reg + "': no registered scans of " + a->db + " found");
    if (missing) cli::warn(fmt::format("{} scans of the database have no registration", missing));
    write_text_file(a->csv.empty() ? reg / "evaluation.csv" : fs::path(a->csv), csv);
    if (!a->flipped_csv.empty()) write_text_file(a->flipped_csv, flipped_rows);
    if (!a->hole_csv.empty()) write_text_file(a->hole_csv, hole_rows);
    fmt::print("registration vs truth, {} scans\n", evaluated);
    fmt::print("  correspondence error   median of per-scan means {:8.3f} mm   (target <= 5)\n",
               percentile(scan_means, 0.5));
    fmt::print("                         95th percentile, all vertices {:8.3f} mm   (target <= 15)\n",
               percentile(all_vertices, 0.95));
    fmt::print("  surface fit            mean over scans {:8.3f} mm   (target <= 1.5)\n",
               std::accumulate(surface_means.begin(), surface_means.end(), 0.0) /
                   surface_means.size());
    fmt::print("  hole error             max inside holes {:8.3f} mm, median of per-scan max "
               "{:.3f} mm   (target <= 20)\n",
               worst_hole, percentile(hole_max, 0.5));
    fmt::print("  flipped triangles      {} in total (target 0)\n", flipped_total);
    fmt::print("    of which the truth itself is folded there   {}   (linear blend skinning collapsed "
               "a crease of the synthetic body: triangle against its 2-ring, unlike at rest)\n",
               flipped_truth_folded_total);
    fmt::print("    of which the scanner did not see them       {}   (all three vertices' true "
               "positions > 5 mm from every scan point)\n",
               flipped_unseen_total);
    fmt::print("    seen, where the truth is not folded         {}\n", flipped_seen_unfolded_total);
    fmt::print("  locally folded         {} in the registrations, {} in the truths   (triangle "
               "against its 2-ring, unlike at rest: needs no truth)\n",
               folded_registration_total, folded_truth_total);
    if (!joint_all.empty())
      fmt::print("  joint rotation error   median {:6.3f} deg, 95th percentile {:6.3f} deg over "
                 "{} major joints × scans   (target median <= 5)\n",
                 percentile(joint_all, 0.5), percentile(joint_all, 0.95), joint_all.size());
    if (a->flipped_regions)
      for (const auto& [region, count] : flipped_by_region)
        fmt::print("    flipped in {:<14} {:5}   ({} unseen)\n", region, count,
                   flipped_unseen_by_region[region]);
    if (a->per_joint && !joint_all.empty())
      for (size_t j = 0; j < joints.size(); ++j)
        fmt::print("    {:<14} median {:6.2f} deg, max {:6.2f} deg   (swing median {:6.2f}, "
                   "twist median {:6.2f})\n",
                   sk.names[joints[j]], percentile(per_joint[j], 0.5),
                   *std::max_element(per_joint[j].begin(), per_joint[j].end()),
                   percentile(per_swing[j], 0.5), percentile(per_twist[j], 0.5));
    if (a->per_joint && !finger_all.empty())
      fmt::print("    distal phalanges (not major joints) median {:6.2f} deg, 95th percentile "
                 "{:6.2f} deg\n",
                 percentile(finger_all, 0.5), percentile(finger_all, 0.95));
  });
}

}  // namespace bodymodel
