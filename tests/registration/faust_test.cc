// Registration of a real body with ground truth: FAUST's tr_reg_000 (a real person standing,
// 6 890 vertices in metres, the data set's own topology; shared/data/faust-registrations) from a
// dense sampling of the mesh, as `register-mesh` does, with the data set's landmark file
// (registration/landmarks/faust.json, placed once by vertex index) less four landmarks held
// out. The held-out landmarks are body points with known truth on both meshes: their error is a
// correspondence error the fit was not told. Skipped, with a message, without the data.
// A short schedule (20 non-rigid steps, 10 pose iterations) keeps it within CI's budget.
// Measured: held-out landmarks worst 18.2 mm (bound 30), two-sided distance 3.01 mm (bound 4),
// no local fold left after the untangling (bound 0); 293–423 s wall on a machine shared by five
// builds (the registration register-mesh of the same mesh with the full schedule took 28 s of
// user CPU).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <filesystem>

#include "core/data_path.h"
#include "core/io/mesh_io.h"
#include "core/landmarks.h"
#include "core/makehuman.h"
#include "registration/fit_check.h"
#include "registration/fold_untangle.h"
#include "registration/local_fold_repair.h"
#include "registration/mesh_scan.h"
#include "registration/metrics.h"
#include "registration/register_scan.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

const fs::path kLandmarks = fs::path(__FILE__).parent_path().parent_path().parent_path() /
                            "registration" / "landmarks" / "faust.json";

fs::path faust_mesh(const std::string& name) {
  try {
    return data_root() / "faust-registrations" / name;
  } catch (const std::exception&) {
    return {};
  }
}

TEST(FaustRegistration, HeldOutLandmarksSurfaceAndFoldsWithinBounds) {
  const fs::path path = faust_mesh("tr_reg_000.off");
  if (path.empty() || !fs::exists(path))
    GTEST_SKIP() << "faust-registrations not found under the data root (BODYMODEL_DATA): "
                    "real-body registration not checked";
  const auto t0 = std::chrono::steady_clock::now();
  MakeHuman mh = MakeHuman::load();
  MakeHuman::Body body = mh.body(MacroSettings{});
  const RegistrationTemplate tpl{body.mesh, body.skeleton, body.weights, mh, MacroSettings{}, {}, {}};
  Mesh mesh = read_mesh(path);
  ASSERT_EQ(mesh.V.rows(), 6890);
  mesh.V *= 1000.0;
  std::vector<Landmark> all = read_mesh_landmarks(kLandmarks, registration_landmarks(), mesh.V);
  ASSERT_EQ(all.size(), registration_landmarks().size());
  const std::vector<std::string> held_out = {"l_elbow", "r_knee", "l_ankle", "r_wrist"};
  std::vector<Landmark> used, checked;
  for (const auto& l : all)
    (std::count(held_out.begin(), held_out.end(), l.name) ? checked : used).push_back(l);
  ASSERT_EQ(checked.size(), held_out.size());
  MeshScanOptions so;
  so.samples = 40000;
  PointCloud scan = mesh_to_scan(mesh, so);
  const PointCloud scan_copy = scan;
  RegistrationOptions options;
  options.nonrigid.fast_k_end = 3.0;  // as register-mesh
  options.nonrigid.fast_steps = 20;
  options.pose.max_icp_iterations = 10;
  RegistrationSummary summary;
  RegistrationResult r = register_scan(tpl, scan, used, options, path.string(), &summary);
  // As register-mesh: folds against the posed template, then local folds.
  unfold_triangles(r.V, r.pose.V, tpl.mesh.F);
  const LocalFoldRepairSummary lf = repair_local_folds(r.V, r.rest.V, tpl.mesh.F);
  // Then the untangling, against the fitted and the start body as the job does.
  const UntangleSummary un =
      untangle_local_folds(r.V, std::vector<Eigen::MatrixX3d>{r.rest.V, tpl.mesh.V}, tpl.mesh.F);

  // Held-out landmarks: the template's landmark vertex against the FAUST vertex the landmark
  // file names (the same body point on every FAUST mesh).
  double worst = 0;
  for (const auto& l : checked) {
    const double e = (r.V.row(l.vertex).transpose() - l.target).norm();
    worst = std::max(worst, e);
    RecordProperty(l.name + "_mm", std::to_string(e));
    EXPECT_LE(e, 30.0) << l.name;
  }
  const MeshScanDistance d = mesh_scan_distance(r.V, tpl.mesh.F, mesh, &r.pose.V);
  EXPECT_LE(d.two_sided_mean, 4.0) << "registered→mesh " << d.registered_to_scan_mean
                                   << " mm, mesh→registered " << d.scan_to_registered_mean;
  // Folds: local folds (a triangle facing against its 2-ring, unlike at rest), the measure that
  // needs no reference pose, counted against the default body as eval-correspondence does:
  // none after the untangling (armpits, elbow creases, ears, eyelids before the repairs), which
  // moves no vertex farther than 20 mm. d.folded_triangles, against the pose-fitted template, is
  // reported only: that template is posed by skinning and creased itself, and unfolding a
  // crease turns triangles against it.
  const std::vector<char> folds = locally_folded_triangles(r.V, body.mesh.V, tpl.mesh.F);
  const int folded = int(std::count(folds.begin(), folds.end(), 1));
  EXPECT_EQ(folded, 0);
  EXPECT_EQ(un.folded_after, 0);
  EXPECT_LE(un.max_displacement, 20.0);
  const FitCheck fc = check_registration_fit(r.V, r.pose.V, r.rest.V, tpl.mesh.F, scan_copy);
  EXPECT_TRUE(fc.plausible) << fc.reason;
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("tr_reg_000: held-out landmarks worst %.1f mm; two-sided %.2f mm; %d folded "
              "against the posed template, %d locally folded (%d before their repair, %d before "
              "the untangling, which moved vertices up to %.1f mm); fit check %.1f mm scan→reg, "
              "%.1f mm moved; %.1f s\n",
              worst, d.two_sided_mean, d.folded_triangles, folded, lf.folded_before, un.folded_before,
              un.max_displacement,
              fc.scan_to_registered_mm, fc.mean_displacement_mm, seconds);
}

}  // namespace
}  // namespace bodymodel
