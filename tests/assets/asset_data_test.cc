// MakeHuman's own assets ($BODYMODEL_DATA/makehuman/assets, README §12) on MakeHuman bodies:
// every binding against its OBJ, assets on morphed and posed bodies, and body-through-cloth
// penetration with its fix. Skipped with a message when the data is missing.
#include <gtest/gtest.h>

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "assets/dress.h"
#include "assets/fit.h"
#include "assets/helpers.h"
#include "assets/rig_carry.h"
#include "assets/penetration.h"
#include "core/data_path.h"
#include "core/error.h"
#include "core/io/bvh.h"
#include "core/retarget.h"
#include "core/makehuman.h"
#include "core/skeleton.h"
#include "core/statistics.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

fs::path assets_dir() {
  try {
    const fs::path d = data_root() / "makehuman" / "assets";
    return fs::is_directory(d) ? d : fs::path();
  } catch (const std::exception&) {
    return {};
  }
}

#define REQUIRE_ASSETS()                                                                      \
  const fs::path dir = assets_dir();                                                          \
  if (dir.empty()) GTEST_SKIP() << "makehuman/assets not found under the data root (BODYMODEL_DATA)"

const MakeHuman& mh() {
  static const MakeHuman m = MakeHuman::load();
  return m;
}

double max_row_distance(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B) {
  return (A - B).rowwise().norm().maxCoeff();
}

// The least-squares body that best explains an asset's OBJ through its binding: the positions
// of the body vertices the rows read and the three offset scales are unknowns, solved per axis
// (the binding is linear in both), with a weak pull (1e-3) of each vertex toward base.obj for
// the directions the rows do not determine. Returns the largest residual, mm.
double residual_on_best_body(const Asset& a, const Eigen::MatrixX3d& base_dm) {
  const AssetBinding& b = a.binding;
  std::map<int, int> col;
  for (int i = 0; i < b.vertex_count(); ++i)
    for (int k = 0; k < 3; ++k)
      if (b.weights(i, k) != 0) col.emplace(b.vertices(i, k), 0);
  int n = 0;
  for (auto& [v, c] : col) c = n++;
  const double lambda = 1e-3;
  Eigen::MatrixX3d residual(b.vertex_count(), 3);
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<Eigen::Triplet<double>> t;
    for (int i = 0; i < b.vertex_count(); ++i) {
      for (int k = 0; k < 3; ++k)
        if (b.weights(i, k) != 0) t.emplace_back(i, col[b.vertices(i, k)], b.weights(i, k));
      t.emplace_back(i, n, b.offsets(i, axis));
    }
    Eigen::SparseMatrix<double> M(b.vertex_count(), n + 1);
    M.setFromTriplets(t.begin(), t.end());
    Eigen::VectorXd prior(n + 1);
    for (auto& [v, c] : col) prior[c] = base_dm(v, axis);
    prior[n] = 1.0;
    Eigen::SparseMatrix<double> I(n + 1, n + 1);
    I.setIdentity();
    const Eigen::SparseMatrix<double> N = Eigen::SparseMatrix<double>(M.transpose() * M) + lambda * lambda * I;
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(N);
    const Eigen::VectorXd x = solver.solve(M.transpose() * a.obj.V.col(axis) + lambda * lambda * prior);
    residual.col(axis) = M * x - a.obj.V.col(axis);
  }
  return residual.rowwise().norm().maxCoeff() * 100.0;  // dm → mm
}

// Assets whose OBJ was modelled on base.obj itself (found by the measurement below; the rest
// were modelled on other bodies: female and male figures, and two lifted 8.2 dm off the origin).
const std::set<std::string> kModelledOnBase = {"fedora", "fedora_cocked", "eyelashes02", "eyelashes03",
                                               "eyelashes04", "short04", "low-poly"};

TEST(AssetData, EveryBindingReproducesItsObj) {
  REQUIRE_ASSETS();
  const std::vector<fs::path> files = find_asset_files(dir);
  ASSERT_GE(files.size(), 1u);
  const Eigen::MatrixX3d base = mh().base_vertices();  // mm
  std::set<std::string> on_base;
  std::printf("%-26s %6s %10s %10s\n", "asset", "verts", "base mm", "best mm");
  for (const fs::path& f : files) {
    SCOPED_TRACE(f.string());
    const Asset a = load_asset(f);
    const std::string stem = f.stem().string();
    ASSERT_LT(a.binding.max_vertex_index(), MakeHuman::kVertexCount);
    // MakeHuman's placement on base.obj against the OBJ (dm → mm).
    const double on_base_mm = max_row_distance(fit_asset(a.binding, base), a.obj.V * 100.0);
    const double best_mm = residual_on_best_body(a, base / 100.0);
    std::printf("%-26s %6d %10.4f %10.4f\n", stem.c_str(), a.binding.vertex_count(), on_base_mm, best_mm);
    if (on_base_mm <= 0.1) on_base.insert(stem);
    if (kModelledOnBase.count(stem)) EXPECT_LE(on_base_mm, 0.1);
    else EXPECT_GT(on_base_mm, 1.0) << "now modelled on base.obj: update kModelledOnBase and docs/assets.md";
    // Every OBJ is the binding evaluated on SOME body. male_worksuit01 is the one exception
    // at 0.33 mm (a few vertices moved after binding, docs/assets.md).
    EXPECT_LE(best_mm, stem == "male_worksuit01" ? 0.5 : 0.1);
  }
  EXPECT_EQ(on_base, kModelledOnBase);
}

// The body the tests dress: all 19158 vertices, mm, with its skeleton and weights.
struct Dressed {
  Eigen::MatrixX3d full;
  Skeleton skeleton;
};

Dressed make_body(const MacroSettings& s) {
  Dressed d;
  d.full = mh().build_vertices(s);
  d.skeleton = mh().skeleton(d.full);
  return d;
}

MacroSettings heavy_tall_man() {
  MacroSettings s;
  s.gender = 1;
  s.weight = 0.9;
  s.height = 0.8;
  s.muscle = 0.7;
  return s;
}

Pose static_pose(const std::string& name, const Skeleton& sk) {
  return bvh_frame_to_pose(read_bvh(mh().pose_file(name)), 0, sk);
}

double percentile(const Eigen::VectorXd& v, double p) {
  return bodymodel::percentile(std::vector<double>(v.data(), v.data() + v.size()), p);
}

TEST(AssetData, GarmentFollowsAMorphedAndPosedBody) {
  REQUIRE_ASSETS();
  const Asset suit = load_asset(dir / "clothes/male_casualsuit01/male_casualsuit01.mhclo");
  // Clearance of the suit over the whole skin (hidden parts included: the visible skin alone
  // is far from most of a suit) on base.obj, on a morphed body, and posed.
  const Eigen::MatrixX3i& F = mh().body_faces();
  const Eigen::MatrixX3d base = mh().base_vertices();
  const Eigen::VectorXd d_base = body_distance(fit_asset(suit.binding, base), base, F).signed_distance;
  const Dressed body = make_body(heavy_tall_man());
  const Eigen::MatrixX3d rest = fit_asset(suit.binding, body.full);
  const Eigen::VectorXd d_morph = body_distance(rest, body.full, F).signed_distance;
  const Eigen::VectorXd change_morph = (d_morph - d_base).cwiseAbs();
  // Had the suit not followed the morph, it would be far off this body.
  const Eigen::VectorXd stale = (body_distance(fit_asset(suit.binding, base), body.full, F).signed_distance - d_base).cwiseAbs();
  std::printf("morph: clearance change median %.2f p95 %.2f mm (unfitted suit: median %.1f p95 %.1f)\n",
              percentile(change_morph, 50), percentile(change_morph, 95), percentile(stale, 50), percentile(stale, 95));
  // The suit is bound to the helper-tights shell, which a heavier body widens a little more than
  // the skin: the clearance changes by a few mm (figures: docs/assets.md), against tens of mm
  // for a suit that did not follow.
  EXPECT_LT(percentile(change_morph, 50), 5.0);
  EXPECT_LT(percentile(change_morph, 95), 15.0);
  EXPECT_GT(percentile(stale, 50), 20.0);

  // Posed: the suit skinned with the weights carried through its binding.
  const SkinWeights W = asset_skin_weights(suit.binding, mh().weights());
  for (const char* pose_name : {"fight01", "sit01", "run01"}) {
    const BoneTransforms M = forward_kinematics(body.skeleton, static_pose(pose_name, body.skeleton));
    const Eigen::MatrixX3d body_posed = linear_blend_skinning(body.full, mh().weights(), M);
    const Eigen::MatrixX3d suit_posed = linear_blend_skinning(rest, W, M);
    const Eigen::VectorXd change = (body_distance(suit_posed, body_posed, F).signed_distance - d_morph).cwiseAbs();
    const Eigen::VectorXd unposed = (body_distance(rest, body_posed, F).signed_distance - d_morph).cwiseAbs();
    std::printf("%s: clearance change median %.2f p95 %.2f mm (unposed suit: median %.1f p95 %.1f)\n", pose_name,
                percentile(change, 50), percentile(change, 95), percentile(unposed, 50), percentile(unposed, 95));
    EXPECT_LT(percentile(change, 50), 1.0) << pose_name;
    EXPECT_LT(percentile(change, 95), 12.0) << pose_name;
    EXPECT_GT(percentile(unposed, 95), 30.0) << pose_name;
  }
}

MacroSettings heavy_short_woman() {
  MacroSettings s;
  s.gender = 0;
  s.weight = 1.0;
  s.height = 0.3;
  s.cup = 0.9;
  return s;
}

// Every garment on two morphed bodies, at rest and in two poses: the fraction of its vertices
// the body pokes through by more than 2 mm, before and after push_garment_out.
TEST(AssetData, PushOutBringsPenetrationUnderOnePercent) {
  REQUIRE_ASSETS();
  std::vector<Asset> garments;
  for (const fs::path& f : find_asset_files(dir / "clothes")) garments.push_back(load_asset(f));
  std::printf("%-6s %-22s %-8s %8s %8s %9s %8s\n", "body", "garment", "frame", "before%", "after%", "maxdepth",
              "maxmove");
  double worst_before = 0, worst_after = 0;
  for (const auto& [body_name, settings] : {std::pair{"man", heavy_tall_man()}, std::pair{"woman", heavy_short_woman()}}) {
    const Dressed body = make_body(settings);
    std::vector<std::pair<std::string, BoneTransforms>> frames = {
        {"rest", forward_kinematics(body.skeleton, Pose::rest(body.skeleton.bone_count()))}};
    for (const char* name : {"fight01", "sit01"})
      frames.emplace_back(name, forward_kinematics(body.skeleton, static_pose(name, body.skeleton)));
    for (const auto& [frame, M] : frames) {
      const Eigen::MatrixX3d body_posed = linear_blend_skinning(body.full, mh().weights(), M);
      for (const Asset& g : garments) {
        const std::vector<char> hidden = hidden_body_vertices({&g.binding}, MakeHuman::kVertexCount);
        const SkinWeights W = asset_skin_weights(g.binding, mh().weights());
        const Eigen::MatrixX3d posed = linear_blend_skinning(fit_asset(g.binding, body.full), W, M);
        const PushOutResult r = push_garment_out(posed, g.faces, body_posed, mh().body_faces(), hidden);
        std::printf("%-6s %-22s %-8s %8.2f %8.2f %9.1f %8.1f\n", body_name, g.file.stem().c_str(), frame.c_str(),
                    100 * r.before.fraction, 100 * r.after.fraction, r.before.max_depth, r.max_move);
        EXPECT_LT(r.after.fraction, 0.01) << body_name << " " << g.file.stem() << " " << frame;
        worst_before = std::max(worst_before, r.before.fraction);
        worst_after = std::max(worst_after, r.after.fraction);
      }
    }
  }
  std::printf("worst garment-frame: before %.2f %%, after %.2f %%\n", 100 * worst_before, 100 * worst_after);
  EXPECT_GT(worst_before, 0.01);  // the fix had something to do
}

// A body with only its 13380 skin vertices gets its helpers from a regressor fitted on random
// MakeHuman bodies, or from a tie made on the default human. The tie cannot follow the helper
// shells sliding along the skin between bodies (about a centimetre); the regressor mostly can
// (a few mm; more on an extreme heavy, short woman).
TEST(AssetData, HelpersFromTheSkinAlone) {
  REQUIRE_ASSETS();
  const HelperBinding tie = bind_helpers(mh().build_vertices(MacroSettings{}), mh().body_faces());
  const HelperRegressor reg = fit_helper_regressor(mh());
  EXPECT_LT((Eigen::VectorXd(reg.R * Eigen::VectorXd::Ones(MakeHuman::kBodyVertexCount)).array() - 1).abs().maxCoeff(), 1e-9);
  const Asset suit = load_asset(dir / "clothes/male_casualsuit01/male_casualsuit01.mhclo");
  const Asset hair = load_asset(dir / "hair/bob01/bob01.mhclo");
  MacroSettings thin_old;
  thin_old.age = 0.9;
  thin_old.weight = 0.1;
  thin_old.gender = 0.3;
  std::printf("%-6s %-9s %11s %9s %9s %14s %14s %9s\n", "body", "method", "tights p95", "suit p95", "suit max",
              "clearance p50", "clearance p95", "hair max");
  for (const auto& [name, s] : {std::pair{"man", heavy_tall_man()}, std::pair{"woman", heavy_short_woman()},
                                std::pair{"thin", thin_old}}) {
    const Eigen::MatrixX3d truth = mh().build_vertices(s);
    const Eigen::MatrixX3d skin = truth.topRows(MakeHuman::kBodyVertexCount);
    for (const bool use_regressor : {false, true}) {
      const Eigen::MatrixX3d made = use_regressor ? complete_with_helpers(reg, skin) : complete_with_helpers(tie, skin);
      EXPECT_EQ((made.topRows(MakeHuman::kBodyVertexCount) - skin).norm(), 0.0);
      const Eigen::VectorXd tights = (made - truth).middleRows(15328, 2674).rowwise().norm();
      const Eigen::MatrixX3d suit_true = fit_asset(suit.binding, truth), suit_made = fit_asset(suit.binding, made);
      const Eigen::VectorXd suit_err = (suit_made - suit_true).rowwise().norm();
      const Eigen::VectorXd clearance = (body_distance(suit_made, truth, mh().body_faces()).signed_distance -
                                         body_distance(suit_true, truth, mh().body_faces()).signed_distance).cwiseAbs();
      const double hair_max = max_row_distance(fit_asset(hair.binding, made), fit_asset(hair.binding, truth));
      std::printf("%-6s %-9s %11.2f %9.2f %9.2f %14.2f %14.2f %9.2f\n", name, use_regressor ? "regressor" : "tie",
                  percentile(tights, 95), percentile(suit_err, 95), suit_err.maxCoeff(), percentile(clearance, 50),
                  percentile(clearance, 95), hair_max);
      // Bounds a little above the figures measured (docs/assets.md): the regressor's are tighter.
      EXPECT_LT(percentile(suit_err, 95), use_regressor ? 10.0 : 25.0) << name;
      EXPECT_LT(percentile(clearance, 95), use_regressor ? 4.5 : 6.0) << name;
      EXPECT_LT(hair_max, use_regressor ? 4.0 : 25.0) << name;
    }
  }
}

// A posed, dressed body: the skin under the outfit is gone, every part is where its binding puts
// it, the garments end under 1 % penetration, and eyes and teeth (inside the head) are not pushed.
TEST(AssetData, DressedBodyHasItsPartsAndHiddenSkin) {
  REQUIRE_ASSETS();
  std::vector<Asset> outfit;
  for (const char* name : {"female_sportsuit01", "shoes02", "ponytail01", "eyebrow003", "high-poly", "teeth_base"})
    outfit.push_back(load_asset(find_asset(dir, name)));
  const Dressed body = make_body(heavy_short_woman());
  const BoneTransforms M = forward_kinematics(body.skeleton, static_pose("sit01", body.skeleton));
  const std::vector<DressedPart> parts = dress_body(body.full, mh().body_faces(), mh().weights(), &M, outfit);
  ASSERT_EQ(parts.size(), outfit.size() + 1);
  EXPECT_EQ(parts[0].name, "body");
  std::vector<const AssetBinding*> worn;
  for (const Asset& a : outfit) worn.push_back(&a.binding);
  const Eigen::Index visible =
      visible_faces(mh().body_faces(), hidden_body_vertices(worn, MakeHuman::kVertexCount)).rows();
  EXPECT_EQ(parts[0].F.rows(), visible);
  EXPECT_LT(visible, mh().body_faces().rows() - 5000);  // the suit and shoes hide a third of the skin
  const SkinWeights W = mh().weights();
  for (size_t k = 0; k < outfit.size(); ++k) {
    const DressedPart& p = parts[k + 1];
    EXPECT_EQ(p.V.rows(), outfit[k].binding.vertex_count());
    EXPECT_EQ(p.garment, p.kind == "clothes") << p.name;
    const Eigen::MatrixX3d plain =
        linear_blend_skinning(fit_asset(outfit[k].binding, body.full), asset_skin_weights(outfit[k].binding, W), M);
    if (p.garment) {
      EXPECT_LT(p.after.fraction, 0.01) << p.name;
      EXPECT_LE(p.after.fraction, p.before.fraction) << p.name;
    } else {
      EXPECT_EQ(max_row_distance(p.V, plain), 0.0) << p.name;
    }
  }
  EXPECT_EQ(asset_kind(outfit[4]), "eyes");
  EXPECT_TRUE(asset_colour(outfit[1]).isApprox(Eigen::Vector3d(0.16, 0.12, 0.10)));  // shoes: our palette
  EXPECT_THROW(dress_body(body.full, mh().body_faces(), mh().weights(), &M,
                          {load_asset(find_asset(dir, "proxy741"))}),
               InputError);
}

// A skin-only LBS rig (as the characters have) extended to the helpers and carried to a suit:
// the helpers pose close to MakeHuman's own helper weights, the suit close to its carried
// MakeHuman weights, and the MWE form of the same rig poses the suit exactly as the mixed weights.
TEST(AssetData, RigsCarriedToAnAsset) {
  REQUIRE_ASSETS();
  const Asset suit = load_asset(dir / "clothes/male_casualsuit01/male_casualsuit01.mhclo");
  const Dressed body = make_body(heavy_tall_man());
  const int nb = MakeHuman::kBodyVertexCount;
  const SkinningRig skin = lbs_rig_from_weights(body.full.topRows(nb), Eigen::MatrixXd(mh().body_weights()), 8);
  const HelperBinding hb = bind_helpers(mh().build_vertices(MacroSettings{}), mh().body_faces());
  const SkinningRig full = extend_rig_to_helpers(skin, hb, body.full);
  const Eigen::MatrixX3d rest = fit_asset(suit.binding, body.full);
  const SkinningRig lbs = carry_rig(suit.binding, full, rest), mwe = carry_rig(suit.binding, lbs_as_mwe(full), rest);
  EXPECT_THROW(carry_rig(suit.binding, skin, rest), InputError);  // reads helper rows the skin rig lacks
  for (const char* pose_name : {"fight01", "sit01"}) {
    const BoneTransforms M = forward_kinematics(body.skeleton, static_pose(pose_name, body.skeleton));
    const Eigen::MatrixX3d truth = linear_blend_skinning(body.full, mh().weights(), M);
    const Eigen::VectorXd tights = (evaluate_rig(full, M) - truth).middleRows(15328, 2674).rowwise().norm();
    const Eigen::MatrixX3d suit_mh = linear_blend_skinning(rest, asset_skin_weights(suit.binding, mh().weights()), M);
    const Eigen::VectorXd suit_err = (evaluate_rig(lbs, M) - suit_mh).rowwise().norm();
    // MWE coefficients are mixed without renormalising: the same as LBS with the raw mix.
    const Eigen::MatrixXd mixed = carry_through_binding(suit.binding, dense_weights(full));
    SkinWeights raw = mixed.sparseView();
    const double mwe_vs_mix = max_row_distance(evaluate_rig(mwe, M), linear_blend_skinning(rest, raw, M));
    const Eigen::MatrixX3d body_posed = evaluate_rig(full, M).topRows(nb);
    const Eigen::VectorXd clearance =
        (body_distance(evaluate_rig(lbs, M), body_posed, mh().body_faces()).signed_distance -
         body_distance(suit_mh, truth, mh().body_faces()).signed_distance).cwiseAbs();
    std::printf("%s: skin rig vs MakeHuman's weights: tights p95 %.2f mm; suit p95 %.2f max %.2f mm, clearance "
                "p50 %.2f p95 %.2f mm; MWE vs mixed weights %.2g mm\n", pose_name, percentile(tights, 95),
                percentile(suit_err, 95), suit_err.maxCoeff(), percentile(clearance, 50), percentile(clearance, 95),
                mwe_vs_mix);
    // MakeHuman weights its helpers on their own (not as the skin under them): the suit lands about
    // a centimetre away along the body, its clearance over the skin changes by a few mm.
    EXPECT_LT(percentile(tights, 95), 15.0) << pose_name;
    EXPECT_LT(percentile(suit_err, 95), 15.0) << pose_name;
    EXPECT_LT(percentile(clearance, 95), 8.0) << pose_name;
    EXPECT_LT(mwe_vs_mix, 1e-6) << pose_name;
  }
  const SkinningRig as{SkinningMethod::animation_space, full.bone_count, full.rest, full.influences,
                       Eigen::MatrixXd::Zero(full.rest.rows(), 4 * full.max_influences())};
  EXPECT_THROW(carry_rig(suit.binding, as, rest), InputError);
}

// Garments through a whole CMU clip (retargeted to the default skeleton), every 12th frame: the
// frames where the body pokes through more than 1 % of a garment's vertices by more than 2 mm,
// (1) skinned as fitted, (2) pushed out frame by frame, (3) pushed out once at rest and then
// skinned, as a runtime (a glb on the GPU) does.
TEST(AssetData, ClipFramesUnderOnePercentAfterTheFix) {
  REQUIRE_ASSETS();
  const Dressed body = make_body(heavy_tall_man());
  const BvhMotion clip = read_bvh(mh().directory() / "motion/cmu/02_02.bvh");
  const Retargeter rt(clip, body.skeleton, RetargetMap::for_clip(clip, mh().directory()));
  for (const char* name : {"male_casualsuit01", "female_elegantsuit01", "male_worksuit01"}) {
    const Asset g = load_asset(find_asset(dir, name));
    const std::vector<char> hidden = hidden_body_vertices({&g.binding}, MakeHuman::kVertexCount);
    const Eigen::MatrixX3d rest = fit_asset(g.binding, body.full);
    const SkinWeights W = asset_skin_weights(g.binding, mh().weights());
    // The runtime route: the garment pushed out once, at rest, then skinned.
    const Eigen::MatrixX3d rest_fixed = push_garment_out(rest, g.faces, body.full, mh().body_faces(), hidden).V;
    int frames = 0, bad[3] = {0, 0, 0};
    double worst[3] = {0, 0, 0};
    for (int f = 0; f < rt.frame_count(); f += 12, ++frames) {
      const BoneTransforms M = forward_kinematics(body.skeleton, rt.pose(f));
      const Eigen::MatrixX3d body_posed = linear_blend_skinning(body.full, mh().weights(), M);
      const PushOutResult r = push_garment_out(linear_blend_skinning(rest, W, M), g.faces, body_posed,
                                               mh().body_faces(), hidden);
      const Penetration once =
          penetration_of(body_distance(linear_blend_skinning(rest_fixed, W, M), body_posed, mh().body_faces(), hidden));
      const double fr[3] = {r.before.fraction, r.after.fraction, once.fraction};
      for (int k = 0; k < 3; ++k) {
        bad[k] += fr[k] > 0.01;
        worst[k] = std::max(worst[k], fr[k]);
      }
    }
    std::printf("%-22s 02_02, %d frames over 1 %%: as fitted %d (worst %.2f %%), fixed per frame %d (%.2f %%), "
                "fixed at rest %d (%.2f %%)\n", name, frames, bad[0], 100 * worst[0], bad[1], 100 * worst[1], bad[2],
                100 * worst[2]);
    EXPECT_EQ(bad[1], 0) << name;
    // Fixing the rest shape does not carry through the clip: what pokes through in motion comes
    // from the pose, where garment and skin skin differently (the worksuit: the upper arms).
    // Recorded, not required (docs/assets.md).
    EXPECT_LE(worst[2], worst[0] + 0.001) << name;
  }
}

}  // namespace
}  // namespace bodymodel
