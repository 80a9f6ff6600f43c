// MakeHuman hm08 body model: base mesh + macro targets + default skeleton + skinning weights.
//
// Reads the CC0 MakeHuman 1.3 data in $BODYMODEL_DATA/makehuman (see its README):
//   base/base.obj                      19158 vertices (decimetres), group "body" = 0..13379
//   targets/macrodetails/**, breast/   the 564 macro targets, blended by the slider rule (§5.2)
//   rig/default.mhskel                 163 bones, joints = mean of listed vertices (§6.1)
//   rig/default_weights.mhw            skinning weights, normalised on load (§6.2)
//   motion/poses/*.bvh                 static poses for the default skeleton (§7.1)
// Everything this class returns is in MILLIMETRES (file decimetres × 100).
//
// Load once (a fraction of a second of CPU: 564 target files, ~350 distinct (hard links are parsed once),
// read in parallel with a hand-written exact decimal parser), then build many bodies: one
// body (vertices + skeleton) costs a few milliseconds.
// Copies of a MakeHuman share the loaded data (cheap to copy, safe to use from many threads).
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <utility>
#include <vector>

#include "core/mesh.h"
#include "core/skeleton.h"

namespace bodymodel {

// MakeHuman macro sliders, each in [0, 1] (README §5.2). Defaults = MakeHuman's default human.
struct MacroSettings {
  double gender = 0.5;       // 0 female … 1 male
  double age = 0.5;          // 0 → 1 y, 0.1875 → 10 y, 0.5 → 25 y, 1 → 90 y
  double muscle = 0.5, weight = 0.5, height = 0.5, proportions = 0.5;
  double cup = 0.5, firmness = 0.5;  // breast size and firmness (female bodies only)
  double african = 1.0 / 3, asian = 1.0 / 3, caucasian = 1.0 / 3;  // sum to 1

  // Keys as in derived/reference_builds.tsv ("gender", "age", ..., "african", "asian",
  // "caucasian"); missing keys keep their defaults. When only some ethnic keys are given the
  // others share the remainder in proportion to their defaults, as MakeHuman does.
  // Throws InputError for an unknown key, a non-number or a value outside [0, 1].
  static MacroSettings from_json(const nlohmann::json& j);
  nlohmann::json to_json() const;
  // Sets one ethnic weight and rescales the other two in proportion so the sum stays 1.
  void set_ethnic(const std::string& which, double value);
  // Age in years: 1 + 48a for a < 0.5, 25 + 130(a − 0.5) otherwise.
  double age_years() const;
  // Throws InputError naming the slider if one is outside [0, 1] or not finite.
  void validate() const;
};

class MakeHuman {
 public:
  static constexpr int kVertexCount = 19158;      // all hm08 vertices (body + helpers)
  static constexpr int kBodyVertexCount = 13380;  // vertices 0..13379 = group "body"

  struct Options {
    // README §10.1: {male,female}-old-maxmuscle-maxweight-minheight.target move only 453 / 1717
    // vertices (their siblings ~19k), so an old, muscular, heavy, short body keeps ~170 cm.
    // When true, each is replaced by its <gender>-old-averagemuscle-maxweight-minheight
    // sibling (which the other minheight files of that gender and age mostly equal). The
    // substitution only happens when the file really is defective (touches < 25% of the
    // substitute's vertices), so a fixed upstream file is used as is. false = raw MakeHuman.
    bool substitute_defective_height_targets = true;
  };

  // Loads base mesh, targets, skeleton and weights from `makehuman_dir`. Throws InputError
  // naming the file (and line) on any malformed or missing input.
  static MakeHuman load(const std::filesystem::path& makehuman_dir, const Options& options);
  static MakeHuman load(const std::filesystem::path& makehuman_dir);
  static MakeHuman load();  // data_file("makehuman")
  // The same loaded data with other options (cheap: the parsed targets are shared).
  MakeHuman with_options(const Options& options) const;

  // All 19158 vertices (#V by 3, mm) of the body with these sliders.
  Eigen::MatrixX3d build_vertices(const MacroSettings& settings) const;

  // MakeHuman's 20 measurement modifiers (README §5.2 "Measure targets", targets/measure/):
  // names without the "measure-" prefix ("neck-circ", ..., "waist-circ", ...) in
  // modifiers/measurement_modifiers.json order; empty when the data has no targets/measure
  // folder. A modifier value v gives the decr target weight max(0, −v) and the incr weight
  // max(0, v); MakeHuman's sliders span v in [−1, 1].
  const std::vector<std::string>& measure_modifier_names() const;
  // Index of a modifier name, −1 when unknown.
  int measure_modifier_index(const std::string& name) const;

  // Options of the extended build below.
  struct BuildOptions {
    // false: every macro slider in [0, 1] and every modifier in [−1, 1] (MakeHuman's own
    // range; InputError otherwise). true: any finite value; beyond the range the targets are
    // extrapolated LINEARLY along their last segment (e.g. weight 1.25 gives maxweight 1.5,
    // averageweight −0.5), which is what fit-measurements' extended space uses. Ethnic weights
    // and gender must stay in [0, 1] either way.
    bool allow_extrapolation = false;
  };
  // The body with macro sliders AND measurement modifiers (`modifiers`: one value per
  // measure_modifier_names(), or empty = all 0). All 19158 vertices, mm.
  Eigen::MatrixX3d build_vertices(const MacroSettings& settings, const Eigen::VectorXd& modifiers,
                                  const BuildOptions& options) const;
  // The offsets (19158 by 3, mm) of one modifier at v = +1 (incr) or v = −1 (decr): the mesh is
  // linear in each modifier on either side of 0.
  Eigen::MatrixX3d measure_modifier_offsets(int modifier, bool increase) const;
  // MakeHuman's body-shape modifiers (data README §12), loaded on first use: the groups armslegs,
  // torso, hip, stomach, buttocks, neck and pelvis of modifiers/modeling_modifiers.json, two-sided
  // (a value v in [−1, 1] weighs the `min` target by max(0, −v) and the `max` one by max(0, v)),
  // and bodyshapes_modifiers.json, one-sided (v in [0, 1] weighs its one target). Named as
  // MakeHuman names them: "torso/torso-scale-depth-decr|incr", "bodyshapes/bodyshapes-elvs-man-apple".
  // Modifiers whose target files are missing are left out; empty when targets/ has none.
  struct ShapeModifier {
    std::string name, group;
    bool two_sided = true;
    // "l", "r" for one side's limb modifiers ("armslegs/l-upperarm-fat-decr|incr"), else empty;
    // `mirror` is the index of the other side's modifier (−1 when none).
    std::string side;
    int mirror = -1;
  };
  const std::vector<ShapeModifier>& shape_modifiers() const;
  // Index of a shape-modifier name, −1 when unknown.
  int shape_modifier_index(const std::string& name) const;
  // Adds modifier k's offsets at value `value` (mm) to V (#V by 3, mm; rows beyond V's are
  // skipped, so the 13380 body vertices alone work): the mesh is linear in each shape modifier
  // on either side of 0.
  void add_shape_modifier(Eigen::MatrixX3d& V, int k, double value) const;
  // The body with macro sliders, measurement modifiers (empty = all 0) and shape modifiers (one
  // per shape_modifiers(), or empty = all 0); beyond [−1, 1] ([0, 1] one-sided) only with
  // allow_extrapolation, as for the measurement modifiers. All 19158 vertices, mm.
  Eigen::MatrixX3d build_vertices(const MacroSettings& settings, const Eigen::VectorXd& modifiers,
                                  const Eigen::VectorXd& shape_modifiers, const BuildOptions& options) const;
  // The raw base.obj vertices (19158 by 3, mm); not the default human (README §5.2).
  const Eigen::MatrixX3d& base_vertices() const;
  // Target files (relative to targets/) with non-zero weight for `settings`, and the weights.
  std::vector<std::pair<std::string, double>> target_weights(const MacroSettings& settings) const;
  // Number of macro target files loaded (564) and of distinct files parsed.
  int target_count() const;
  // Names (relative to targets/) of the defective targets that were substituted.
  std::vector<std::string> substituted_targets() const;

  // Body group quads triangulated (a b c, a c d): 26756 by 3 over vertices 0..13379,
  // counter-clockwise seen from outside.
  const Eigen::MatrixX3i& body_faces() const;
  // Default skeleton (163 bones, parents before children) on `full_vertices` (19158 by 3,
  // mm): every joint is the mean of its listed vertices (README §6.1).
  Skeleton skeleton(const Eigen::MatrixX3d& full_vertices) const;
  // The default skeleton from the 13380 BODY vertices alone (mm), e.g. of a registered scan
  // that has no helper geometry: each joint is a fixed combination (weights summing to 1, so
  // it moves rigidly with the mesh) of 128 body vertices around it, fitted by regularised
  // least squares to reproduce skeleton() over 160 random MakeHuman bodies (fitted once, on
  // first use). On unseen MakeHuman bodies the worst joints are the chest joints of extreme builds
  // (MakeHuman's weight targets move the surface, not the joints; figures: docs/benchmarks.md#figures-behind-code-comments).
  Skeleton skeleton_from_body(const Eigen::MatrixX3d& body_vertices) const;
  // That regressor: #joints by 13380 (rows sum to 1). Thread-safe.
  const Eigen::SparseMatrix<double, Eigen::RowMajor>& body_joint_regressor() const;
  // Skinning weights normalised as MakeHuman does (README §6.2): duplicates merged, each row
  // divided by its sum, weights below 1e-4 dropped, rows renormalised to sum 1.
  const SkinWeights& body_weights() const;  // 13380 by #bones
  const SkinWeights& weights() const;       // 19158 by #bones (helpers included)

  // The trunk and limbs of the body template (13380 entries, 1 = in the region;
  // core/plausibility.h trunk_and_limbs_region with the default skeleton and body weights): the
  // region core/plausibility.h's roughness is reported over.
  std::vector<char> trunk_and_limbs_region() const;

  struct Body {
    Mesh mesh;          // body-only template: V 13380 by 3 (mm), F = body_faces()
    Skeleton skeleton;  // default skeleton on this body (mm)
    SkinWeights weights;  // = body_weights()
  };
  Body body(const MacroSettings& settings) const;
  // The same with measurement modifiers (see build_vertices above).
  Body body(const MacroSettings& settings, const Eigen::VectorXd& modifiers, const BuildOptions& options) const;
  // ... and body-shape modifiers (shape_modifiers(); empty = all 0).
  Body body(const MacroSettings& settings, const Eigen::VectorXd& modifiers, const Eigen::VectorXd& shape_modifiers,
            const BuildOptions& options) const;

  // Stems of motion/poses/*.bvh, sorted ("benchmark", "fight01", ..., "tpose").
  std::vector<std::string> pose_names() const;
  // The file of a pose name (motion/poses/<name>.bvh); InputError listing the names if unknown.
  std::filesystem::path pose_file(const std::string& name) const;
  const std::filesystem::path& directory() const;

  struct Impl;

 private:
  std::shared_ptr<const Impl> impl_;
};

// Parse-only entry points of the readers MakeHuman::load uses, from memory (`name` names the
// input in errors; each throws InputError exactly as load() does). For tests and fuzzing.
// A .target file: the number of "<index> <dx> <dy> <dz>" rows.
int parse_makehuman_target(const std::string& text, const std::string& name,
                           int vertex_count = MakeHuman::kVertexCount);
// A .mhskel file: the bone names in load()'s order (breadth first from the root).
std::vector<std::string> parse_makehuman_skeleton(const std::string& text, const std::string& name);
// A .mhw file for a skeleton with these bones: normalised weights, 19158 by #bones.
SkinWeights parse_makehuman_weights(const std::string& text, const std::string& name,
                                    const std::vector<std::string>& bone_names);

// Body height in mm as MakeHuman measures it: the y-extent of vertices 0..13379
// (V: #V by 3, mm, at least 13380 rows).
double makehuman_body_height(const Eigen::MatrixX3d& V);

}  // namespace bodymodel
