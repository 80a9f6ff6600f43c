// Registration on real captured data: the template registered to frames of the Vlasic et al.
// 2008 "jumping" sequence (animations/vlasic-jumping: a clothed human in metres, 10 002
// vertices, another topology, no landmarks supplied). The landmarks were placed once on the
// first frame as vertex indices (registration/vlasic_jumping_landmarks.json) and are reused
// for every frame. Skipped, with a message, if the data set is not there.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>

#include "core/data_path.h"
#include "core/io/mesh_io.h"
#include "core/landmarks.h"
#include "core/makehuman.h"
#include "registration/detail_transfer.h"
#include "registration/mesh_scan.h"
#include "registration/register_scan.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

fs::path vlasic_frame(const std::string& name) {
  try {
    return data_root() / "animations" / "vlasic-jumping" / name;
  } catch (const std::exception&) {
    return {};
  }
}

const fs::path kLandmarks = fs::path(__FILE__).parent_path().parent_path().parent_path() /
                            "registration" / "vlasic_jumping_landmarks.json";

class VlasicRegistration : public ::testing::TestWithParam<const char*> {};

// Frame 1 (standing) and frame 64 (later in the jump): mean two-sided surface
// distance ≤ 10 mm (issue #3) and no folded triangles, with register-mesh's settings (fast
// schedule ending at β = 3, shape fit, folds smoothed away). Measured with the verb: 7.22 and
// 6.60 mm (7.63 and 9.11 mm without the shape fit).
TEST_P(VlasicRegistration, MeetsTheDistanceBoundWithoutFolds) {
  const fs::path frame = vlasic_frame(GetParam());
  if (frame.empty() || !fs::exists(frame))
    GTEST_SKIP() << "animations/vlasic-jumping not found under the data root "
                    "(BODYMODEL_DATA): real-data registration not checked";
  ASSERT_TRUE(fs::exists(kLandmarks)) << kLandmarks;
  const auto t0 = std::chrono::steady_clock::now();
  MakeHuman mh = MakeHuman::load();
  MakeHuman::Body body = mh.body(MacroSettings{});
  // With the shape space, as register-mesh (macro sliders fitted in the pose stage).
  const RegistrationTemplate tpl{body.mesh, body.skeleton, body.weights, mh, MacroSettings{}, {}, {}};

  Mesh mesh = read_mesh(frame);
  mesh.V *= 1000.0;  // metres → mm
  const std::vector<Landmark> landmarks =
      read_mesh_landmarks(kLandmarks, body_landmarks(), mesh.V);
  EXPECT_GE(landmarks.size(), 12u);
  PointCloud scan = mesh_to_scan(mesh);
  const PointCloud scan_copy = scan;
  RegistrationOptions options;
  options.nonrigid.fast_k_end = 3.0;  // as register-mesh
  RegistrationSummary summary;
  RegistrationResult r = register_scan(tpl, scan, landmarks, options, frame.string(), &summary);
  // The fit folds a few of the template's finest triangles (eyelids, armpits) where the
  // captured mesh has no such detail; the verb smooths them away, as here.
  const int folds_before = folded_triangles(r.V, r.pose.V, tpl.mesh.F);
  EXPECT_EQ(unfold_triangles(r.V, r.pose.V, tpl.mesh.F), 0);
  EXPECT_LT(folds_before, 400);
  const MeshScanDistance d = mesh_scan_distance(r.V, tpl.mesh.F, mesh, &r.pose.V);
  RecordProperty("two_sided_mm", std::to_string(d.two_sided_mean));
  EXPECT_LE(d.two_sided_mean, 10.0) << "registered→scan " << d.registered_to_scan_mean
                                    << " mm, scan→registered " << d.scan_to_registered_mean;
  EXPECT_EQ(d.folded_triangles, 0);
  EXPECT_TRUE(r.V.allFinite());

  // Detail transfer on real data: the scan is closer to the detailed surface than to the fit.
  const SurfaceDetail detail = capture_detail(r.V, tpl.mesh.F, scan_copy);
  const Mesh detailed = apply_detail(r.V, tpl.mesh.F, detail);
  const MeshScanDistance dd = mesh_scan_distance(detailed.V, detailed.F, mesh);
  EXPECT_LT(dd.scan_to_registered_mean, d.scan_to_registered_mean);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("%s: two-sided %.2f mm (reg→scan %.2f, scan→reg %.2f), %d folded (%d before "
              "the repair), %d flipped against the scan; with detail scan→reg %.2f mm; %.1f s\n",
              GetParam(), d.two_sided_mean, d.registered_to_scan_mean, d.scan_to_registered_mean,
              d.folded_triangles, folds_before, d.flipped_against_scan,
              dd.scan_to_registered_mean, seconds);
}

INSTANTIATE_TEST_SUITE_P(Frames, VlasicRegistration,
                         ::testing::Values("mesh_0001.obj", "mesh_0064.obj"),
                         [](const auto& info) {
                           return std::string(info.param).substr(0, 9);
                         });

}  // namespace
}  // namespace bodymodel
