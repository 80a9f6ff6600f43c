// The report's 3D viewer in a real browser: `bodymodel viewer` on three rigs of the MakeHuman
// body (ssd, as, mwe), opened in headless Chromium (tests/tools/viewer_browser.js). Checks that
// the body is drawn where the C++ evaluator puts it, that the clip plays, and that the vertex
// shader's positions (transform feedback) match evaluate_rig to 1e-4 of the body height on 3
// frames, and that a mesh given with --error-mesh is drawn in the colour map with its legend. Skipped, saying why, when chromium or node is missing (scripts/setup.sh installs them).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <random>

#include "core/data_path.h"
#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "core/makehuman.h"
#include "skinning/rig_io.h"
#include "skinning/skinning_rig.h"
#include "support/fixtures.h"
#include "support/run_cli.h"

namespace bodymodel {
namespace {
namespace fs = std::filesystem;
using fixtures::run_cli;

std::string chromium_path() {
  if (const char* c = std::getenv("BODYMODEL_CHROMIUM"); c && *c) return c;
  return "/usr/bin/chromium";
}

TEST(ViewerBrowser, ShaderMatchesTheCppEvaluatorAndDrawsTheBody) {
  if (!fs::exists(chromium_path())) GTEST_SKIP() << chromium_path() << " not found (Debian package chromium; scripts/setup.sh)";
  if (std::system("command -v node >/dev/null 2>&1") != 0) GTEST_SKIP() << "node not found";
  const MakeHuman mh = MakeHuman::load();
  const MakeHuman::Body body = mh.body(MacroSettings{});
  const SkinningRig lbs = lbs_rig_from_weights(body.mesh.V, Eigen::MatrixXd(body.weights), 4);
  // AS and MWE rigs that are not LBS in disguise: each coefficient perturbed (seeded), so a
  // shader that mixed up slots, rows or columns would not match.
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> u(-1, 1);
  SkinningRig as = lbs;
  as.method = SkinningMethod::animation_space;
  as.coefficients.resize(lbs.vertex_count(), 4 * lbs.max_influences());
  for (int v = 0; v < lbs.vertex_count(); ++v)
    for (int k = 0; k < lbs.max_influences(); ++k) {
      const double w = lbs.coefficients(v, k);
      for (int i = 0; i < 3; ++i) as.coefficients(v, 4 * k + i) = w * (lbs.rest(v, i) + 5 * u(rng));
      as.coefficients(v, 4 * k + 3) = w;
    }
  SkinningRig mwe = lbs_as_mwe(lbs);
  for (int v = 0; v < mwe.vertex_count(); ++v)
    for (int c = 0; c < mwe.coefficients.cols(); ++c) mwe.coefficients(v, c) *= 1 + 0.05 * u(rng);

  fixtures::TempDir tmp;
  save_rig(tmp / "ssd.npz", lbs, body.mesh.F, {}, &body.skeleton);
  save_rig(tmp / "as.npz", as, body.mesh.F, {}, &body.skeleton);
  save_rig(tmp / "mwe.npz", mwe, body.mesh.F, {}, &body.skeleton);
  // An error mesh: the body sheared forwards by 0 (feet) to 40 mm (head), so its distance to
  // the body spans the colour map (scale 30 mm): blue at the feet, red at the head.
  Eigen::MatrixX3d sheared = body.mesh.V;
  const double y0 = sheared.col(1).minCoeff(), y1 = sheared.col(1).maxCoeff();
  for (int v = 0; v < sheared.rows(); ++v) sheared(v, 2) += 40 * (sheared(v, 1) - y0) / (y1 - y0);
  write_mesh(tmp / "body.obj", body.mesh.V, body.mesh.F);
  write_mesh(tmp / "sheared.obj", sheared, body.mesh.F);
  const fs::path bvh = data_file("makehuman/motion/cmu/12_03.bvh");
  const fs::path out = tmp / "viewer";
  auto r = run_cli("viewer --rig " + (tmp / "ssd.npz").string() + " --rig " + (tmp / "as.npz").string() + " --rig " +
                   (tmp / "mwe.npz").string() + " --bvh " + bvh.string() + " --frames 24 --every 4 --check-frames 0,11,23 --error-mesh " +
                   (tmp / "sheared.obj").string() + " " + (tmp / "body.obj").string() + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* f : {"index.html", "viewer.js", "viewer_data.js", "three.min.js", "check.json"})
    EXPECT_TRUE(fs::exists(out / f)) << f;

  // The screenshot is kept in the build folder (the test runs from there) for a look.
  fs::create_directories("viewer_test");
  const fs::path script = fs::path(__FILE__).parent_path() / "viewer_browser.js";
  const fs::path log = tmp / "browser.txt";
  const int rc = std::system(("node '" + script.string() + "' '" + out.string() + "' viewer_test/viewer.png '" +
                              chromium_path() + "' > '" + log.string() + "' 2>&1").c_str());
  const std::string text = read_text_file(log);
  if (WIFEXITED(rc) && WEXITSTATUS(rc) == 2) GTEST_SKIP() << text;
  EXPECT_EQ(rc, 0) << text;
  EXPECT_NE(text.find("shader vs C++ mwe"), std::string::npos) << text;
  std::printf("%s", text.c_str());
}

}  // namespace
}  // namespace bodymodel
