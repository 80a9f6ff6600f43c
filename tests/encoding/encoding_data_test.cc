// Integration tests on the shared data: horse-gallop round trip (open mesh with a slit in a
// hoof), MakeHuman bodies in several poses, RRE vs vertex interpolation of a raised arm,
// handles and a masked change on a body.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <filesystem>
#include <random>
#include <set>

#include "core/data_path.h"
#include "core/geometry.h"
#include "core/io/bvh.h"
#include "core/io/mesh_io.h"
#include "core/makehuman.h"
#include "core/retarget.h"
#include "core/skeleton.h"
#include "encoding/relative_rotation_decoder.h"
#include "encoding/relative_rotation_encoding.h"
#include "encoding_test_util.h"

namespace bodymodel {
namespace {

using testing::max_error_after_alignment;
using testing::mean_relative_edge_change;

TEST(EncodingData, HorseGallopEveryFrameRoundTripsWithin1e6OfTheDiagonal) {
  std::vector<Eigen::MatrixX3d> frames;
  Eigen::MatrixX3i F;
  for (int i = 1; i <= 48; ++i) {
    char name[64];
    std::snprintf(name, sizeof name, "animations/horse-gallop/horse-gallop-%02d.obj", i);
    Mesh m = read_mesh(data_file(name));
    if (i == 1) F = m.F;
    frames.push_back(m.V);
    ASSERT_EQ(m.V.rows(), 8431);
    ASSERT_TRUE(m.F == F) << "frame " << i << " has another face list";
  }
  auto tmpl = std::make_shared<const EncodingTemplate>(frames[0], F);
  EXPECT_GT(tmpl->boundary_slot_count(), 0);  // the horse is open (a slit in one hoof)
  const EncodedSet set = encode_set(*tmpl, frames);
  RelativeRotationDecoder decoder(tmpl);
  double worst = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    const Eigen::MatrixX3d X = decoder.decode(set.encodings[i]);
    const double err = max_error_after_alignment(X, frames[i]) / bounding_box_diagonal(frames[i]);
    EXPECT_LT(err, 1e-6) << "frame " << i + 1;
    worst = std::max(worst, err);
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
  std::printf("horse-gallop: 48 frames, worst max-vertex error / bbox diagonal = %.3g\n", worst);
}

// ---- MakeHuman -------------------------------------------------------------------------------

const MakeHuman& makehuman() {
  static const MakeHuman mh = MakeHuman::load();
  return mh;
}

Eigen::MatrixX3d posed(const MakeHuman::Body& body, const Pose& pose) {
  return linear_blend_skinning(body.mesh.V, body.weights, forward_kinematics(body.skeleton, pose));
}

Pose bvh_pose(const MakeHuman::Body& body, const std::string& name) {
  return bvh_frame_to_pose(read_bvh(makehuman().pose_file(name)), 0, body.skeleton);
}

// Bones in the subtree of `root` (root included).
std::vector<char> subtree(const Skeleton& s, int root) {
  std::vector<char> in(s.bone_count(), 0);
  in[root] = 1;
  for (int b = 0; b < s.bone_count(); ++b)
    if (s.parents[b] >= 0 && in[s.parents[b]]) in[b] = 1;
  return in;
}

// Vertices with a non-zero weight on any bone of `bones`.
std::vector<char> influenced(const SkinWeights& W, const std::vector<char>& bones) {
  std::vector<char> v(W.rows(), 0);
  for (int r = 0; r < W.outerSize(); ++r)
    for (SkinWeights::InnerIterator it(W, r); it; ++it)
      if (it.value() > 0 && bones[it.col()]) v[r] = 1;
  return v;
}

// Rest pose with `bone` rotated by `degrees` about the z axis, the sign chosen so the bone's
// subtree moves up (+y): a raised arm for upperarm01.L / .R.
Pose raised(const MakeHuman::Body& body, const std::string& bone, double degrees, Pose pose) {
  const int b = body.skeleton.index(bone);
  const std::vector<char> moved = influenced(body.weights, subtree(body.skeleton, b));
  double best = -1e300;
  Eigen::Matrix3d best_R;
  for (double sign : {1.0, -1.0}) {
    Pose p = pose;
    p.rotations[b] = Eigen::AngleAxisd(sign * degrees * M_PI / 180, Eigen::Vector3d::UnitZ())
                         .toRotationMatrix();
    const Eigen::MatrixX3d V = posed(body, p);
    double y = 0;
    for (Eigen::Index i = 0; i < V.rows(); ++i)
      if (moved[i]) y += V(i, 1);
    if (y > best) best = y, best_R = p.rotations[b];
  }
  pose.rotations[b] = best_R;
  return pose;
}

TEST(EncodingData, MakeHumanBodiesInSeveralPosesRoundTrip) {
  const MakeHuman& mh = makehuman();
  MacroSettings heavy_male, slim_female;
  heavy_male.gender = 1, heavy_male.weight = 0.9, heavy_male.muscle = 0.8;
  slim_female.gender = 0, slim_female.weight = 0.1, slim_female.height = 0.8;
  const std::vector<std::string> poses = {"standing01", "sit01", "fight01", "run01", "tpose"};
  std::shared_ptr<const EncodingTemplate> tmpl;
  std::unique_ptr<RelativeRotationDecoder> decoder;
  std::vector<Eigen::MatrixX3d> meshes;
  for (const MacroSettings& s : {MacroSettings{}, heavy_male, slim_female}) {
    const MakeHuman::Body body = mh.body(s);
    if (!tmpl) {
      tmpl = std::make_shared<const EncodingTemplate>(body.mesh.V, body.mesh.F);
      decoder = std::make_unique<RelativeRotationDecoder>(tmpl);
    }
    meshes.push_back(body.mesh.V);
    for (const auto& p : poses) meshes.push_back(posed(body, bvh_pose(body, p)));
  }
  ASSERT_EQ(tmpl->vertex_count(), 13380);
  ASSERT_EQ(tmpl->triangle_count(), 26756);
  const EncodedSet set = encode_set(*tmpl, meshes);
  double worst = 0;
  for (size_t i = 0; i < meshes.size(); ++i) {
    const Eigen::MatrixX3d X = decoder->decode(set.encodings[i]);
    const double err = max_error_after_alignment(X, meshes[i]) / bounding_box_diagonal(meshes[i]);
    EXPECT_LT(err, 1e-6) << "mesh " << i;
    worst = std::max(worst, err);
  }
  std::printf("MakeHuman: %zu bodies×poses, worst max-vertex error / bbox diagonal = %.3g\n",
              meshes.size(), worst);
}

// Every pose the synthetic scan database draws from: all static poses of motion/poses and
// frames of each retargeted CMU clip (as `synth-db` samples them), on a non-default body.
TEST(EncodingData, EveryPoseOfTheSyntheticDatabaseRoundTrips) {
  const MakeHuman& mh = makehuman();
  MacroSettings s;
  s.gender = 0.9, s.weight = 0.7, s.height = 0.3, s.age = 0.7;
  const MakeHuman::Body body = mh.body(s);
  std::vector<Eigen::MatrixX3d> meshes = {body.mesh.V};
  for (const auto& name : mh.pose_names()) meshes.push_back(posed(body, bvh_pose(body, name)));
  for (const auto& entry : std::filesystem::directory_iterator(mh.directory() / "motion" / "cmu")) {
    if (entry.path().extension() != ".bvh") continue;
    const BvhMotion clip = read_bvh(entry.path());
    const Retargeter retarget(clip, body.skeleton, RetargetMap::for_clip(clip, mh.directory()));
    for (int k = 0; k < 4; ++k)
      meshes.push_back(posed(body, retarget.pose(static_cast<int>((k + 0.5) * clip.frame_count() / 4))));
  }
  ASSERT_GE(meshes.size(), 1u + 14u + 12u);
  const auto tmpl = std::make_shared<const EncodingTemplate>(body.mesh.V, body.mesh.F);
  RelativeRotationDecoder decoder(tmpl);
  const EncodedSet set = encode_set(*tmpl, meshes);
  double worst = 0;
  for (size_t i = 0; i < meshes.size(); ++i) {
    const Eigen::MatrixX3d X = decoder.decode(set.encodings[i]);
    const double err = max_error_after_alignment(X, meshes[i]) / bounding_box_diagonal(meshes[i]);
    EXPECT_LT(err, 1e-6) << "mesh " << i;
    worst = std::max(worst, err);
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
}

TEST(EncodingData, HalfwayToARaisedArmKeepsEdgeLengthsUnlikeVertexInterpolation) {
  const MakeHuman::Body body = makehuman().body(MacroSettings{});
  const Pose rest = Pose::rest(body.skeleton.bone_count());
  const Eigen::MatrixX3d V0 = body.mesh.V;
  const Eigen::MatrixX3d V1 = posed(body, raised(body, "upperarm01.L", 100, rest));
  auto tmpl = std::make_shared<const EncodingTemplate>(V0, body.mesh.F);
  RelativeRotationDecoder decoder(tmpl);
  const EncodedSet set = encode_set(*tmpl, {V0, V1});
  const Eigen::MatrixX3d rre = decoder.decode(interpolate(set.encodings[0], set.encodings[1], 0.5));
  const Eigen::MatrixX3d lin = 0.5 * (V0 + V1);
  const Eigen::MatrixX2i E = unique_edges(body.mesh.F);
  const double change_rre = mean_relative_edge_change(rre, V0, E);
  const double change_lin = mean_relative_edge_change(lin, V0, E);
  const double change_end = mean_relative_edge_change(V1, V0, E);
  std::printf("raised arm (100°), mean relative edge-length change vs rest: RRE halfway %.4f%%, "
              "vertex halfway %.4f%%, raised pose itself %.4f%%\n",
              100 * change_rre, 100 * change_lin, 100 * change_end);
  EXPECT_LE(change_rre, 0.01);
  EXPECT_GE(change_lin, 3 * change_rre);
  // The arm really moved halfway: its vertices are far from both ends.
  EXPECT_GT(max_error_after_alignment(rre, V0), 100.0);
}

TEST(EncodingData, ChangeMaskedToTheLeftArmLeavesTheRestWithin1mm) {
  const MakeHuman::Body body = makehuman().body(MacroSettings{});
  const Skeleton& sk = body.skeleton;
  const Pose rest = Pose::rest(sk.bone_count());
  Pose change = raised(body, "upperarm01.L", 80, rest);
  // ... plus changes elsewhere that the mask must hold back: both knees bent.
  for (const char* knee : {"lowerleg01.L", "lowerleg01.R"})
    change.rotations[sk.index(knee)] =
        Eigen::AngleAxisd(0.8, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::MatrixX3d V0 = body.mesh.V, V1 = posed(body, change);
  auto tmpl = std::make_shared<const EncodingTemplate>(V0, body.mesh.F);
  RelativeRotationDecoder decoder(tmpl);
  const EncodedSet set = encode_set(*tmpl, {V0, V1});
  // Left arm = the triangles the arm bones deform (any vertex weighted by upperarm01.L or its
  // children), grown by one ring so the border of the mask lies where the change is zero.
  const std::vector<char> arm = influenced(body.weights, subtree(sk, sk.index("upperarm01.L")));
  const Eigen::MatrixX3i& F = body.mesh.F;
  std::vector<char> changed_vertex(V0.rows(), 0);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    if (arm[F(f, 0)] || arm[F(f, 1)] || arm[F(f, 2)])
      for (int k = 0; k < 3; ++k) changed_vertex[F(f, k)] = 1;
  Eigen::VectorXd mask = Eigen::VectorXd::Zero(F.rows());
  std::vector<char> inside(V0.rows(), 0);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    if (changed_vertex[F(f, 0)] || changed_vertex[F(f, 1)] || changed_vertex[F(f, 2)]) {
      mask(f) = 1;
      for (int k = 0; k < 3; ++k) inside[F(f, k)] = 1;
    }
  std::vector<char> outside(V0.rows());
  for (Eigen::Index i = 0; i < V0.rows(); ++i) outside[i] = !inside[i];
  const Eigen::MatrixX3d X =
      decoder.decode(masked_change(set.encodings[0], set.encodings[1], mask));
  const double outside_err = max_error_after_alignment(X, V0, outside);
  const double unmasked_err = max_error_after_alignment(decoder.decode(set.encodings[1]), V0, outside);
  std::printf("masked change (left arm): max outside movement %.4g mm (unmasked: %.1f mm)\n",
              outside_err, unmasked_err);
  EXPECT_LT(outside_err, 1.0);
  EXPECT_GT(unmasked_err, 100.0);  // without the mask the legs move
  EXPECT_GT(max_error_after_alignment(X, V0), 100.0);  // the left arm did move
}

// The supernodal block Cholesky (default decoder) against CHOLMOD's scalar refactorisation of
// the same rotation system (RotationSolver::kCholeskyRefactor, the direct reference) on the
// encodings that need a solve: a pose blend with a large change (rest ↔ arm raised 100°), a
// body blend across poses and a model-like random sample (2σ along the set's deviations).
// Both are exact least-squares solves, so they must agree to rounding: ≤ 1e-4 mm on a body
// of ~1700 mm diagonal (6e-8 of the diagonal).
TEST(EncodingData, SupernodalDecodeAgreesWithCholmodOnBlendsAndSamples) {
  const MakeHuman& mh = makehuman();
  MacroSettings heavy;
  heavy.gender = 1, heavy.weight = 0.85, heavy.muscle = 0.7, heavy.height = 0.7;
  const MakeHuman::Body body = mh.body(MacroSettings{}), other = mh.body(heavy);
  const Pose rest = Pose::rest(body.skeleton.bone_count());
  const std::vector<Eigen::MatrixX3d> meshes = {
      body.mesh.V, posed(body, raised(body, "upperarm01.L", 100, rest)),
      posed(body, bvh_pose(body, "fight01")), posed(other, bvh_pose(other, "run01"))};
  auto tmpl = std::make_shared<const EncodingTemplate>(body.mesh.V, body.mesh.F);
  const EncodedSet set = encode_set(*tmpl, meshes);
  const auto& e = set.encodings;
  std::mt19937 rng(7);
  std::normal_distribution<double> z;
  Encoding sample = 0.0 * e[0];
  for (const Encoding& ei : e) sample = sample + (2.0 * z(rng) / std::sqrt(double(e.size()))) * ei;
  DecoderOptions direct;
  direct.rotation_solver = RotationSolver::kCholeskyRefactor;
  const RelativeRotationDecoder fast(tmpl), reference(tmpl, direct);
  const std::vector<std::pair<const char*, Encoding>> cases = {
      {"arm blend", interpolate(e[0], e[1], 0.5)},
      {"body blend", interpolate(e[2], e[3], 0.5)},
      {"sample", sample}};
  for (const auto& [name, enc] : cases) {
    DecodeTiming t;
    const Eigen::MatrixX3d X = fast.decode(enc, {}, &t);
    const Eigen::MatrixX3d Y = reference.decode(enc);
    const double diff = (X - Y).rowwise().norm().maxCoeff();
    std::printf("%s: supernodal vs CHOLMOD decode, max vertex difference %.3g mm\n", name, diff);
    EXPECT_EQ(t.rotation_path, 2) << name;  // really solved (not realisable)
    EXPECT_LE(diff, 1e-4) << name;
    EXPECT_GT(max_error_after_alignment(X, meshes[0]), 10.0) << name;  // not the rest body
  }
}

TEST(EncodingData, TenBodyHandlesMoved50mmLandWithin1mm) {
  const MakeHuman::Body body = makehuman().body(MacroSettings{});
  auto tmpl = std::make_shared<const EncodingTemplate>(body.mesh.V, body.mesh.F);
  RelativeRotationDecoder decoder(tmpl);
  const Eigen::MatrixX3d N = vertex_normals(body.mesh.V, body.mesh.F);
  PositionConstraints c;
  c.vertices.resize(10);
  c.targets.resize(10, 3);
  for (int i = 0; i < 10; ++i) {
    const int v = 1000 + 1231 * i;
    c.vertices(i) = v;
    c.targets.row(i) = body.mesh.V.row(v) + (i % 2 ? 50.0 : -50.0) * N.row(v);
  }
  const Eigen::MatrixX3d X = decoder.decode(encode(*tmpl, body.mesh.V), c);
  double worst = 0;
  for (int i = 0; i < 10; ++i)
    worst = std::max(worst, (X.row(c.vertices(i)) - c.targets.row(i)).norm());
  std::printf("10 handles moved 50 mm: worst distance to target %.4f mm\n", worst);
  EXPECT_LT(worst, 1.0);
  EXPECT_GT(max_error_after_alignment(X, body.mesh.V), 20.0);
}

}  // namespace
}  // namespace bodymodel
