// A dressed body: the body with the skin its assets hide removed, and each asset fitted by its
// binding, skinned with the weights carried through it, garments pushed out of the skin, each
// part with one colour. The library half of `bodymodel dress` (docs/assets.md).
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "assets/fit.h"
#include "assets/helpers.h"
#include "assets/penetration.h"
#include "core/skeleton.h"

namespace bodymodel {

// The asset folder kind: "clothes", "hair", "eyebrows", "eyelashes", "eyes", "teeth",
// "proxymeshes", or "" when the binding does not sit in <kind>/<asset>/ (or <kind>/<asset>.mhclo).
std::string asset_kind(const Asset& asset);

// One colour per asset: the material's diffuse colour when it is not plain white (upstream
// textures are Git LFS pointers, so a white diffuse only means "use the texture"), else a fixed
// colour per kind (our choice, docs/assets.md).
Eigen::Vector3d asset_colour(const Asset& asset);

// The binding file of an asset by name (the stem: "male_casualsuit01", "shoes01", "short02",
// "eyebrow001", "low-poly") under `assets_root`; InputError listing the known names otherwise.
std::filesystem::path find_asset(const std::filesystem::path& assets_root, const std::string& name);

struct DressOptions {
  bool fix_penetration = true;  // push garments ("clothes") out of the visible skin
  PushOutOptions push;
  double depth_mm = 2.0;        // the penetration threshold reported
  Eigen::Vector3d skin_colour{0.82, 0.64, 0.54};
  // dress_skin_body only: garment vertices within `skin_weights_near` mm of the skin take the
  // weights of their closest skin point (skin_weights_at), blended linearly to the weights carried
  // through the binding at `skin_weights_far` mm (a skirt's hem keeps the binding's). The carried
  // weights come from the helper shells, skinned a little differently from the skin beneath:
  // in motion that is what pushes skin through tight cloth (docs/assets.md). < 0 = off.
  double skin_weights_near = -1, skin_weights_far = 30;
};

struct DressedPart {
  std::string name, kind;       // "body" / "body" for the body
  Eigen::MatrixX3d V;           // mm, posed
  Eigen::MatrixX3i F;
  Eigen::Vector3d colour;
  double roughness = 0.8;       // 1 − the material's shininess (our stand-in), else 0.8
  SkinWeights weights;          // #V by #bones: the rows of the body's weights, or carried to the asset
  bool garment = false;         // measured (and pushed) for penetration
  Penetration before, after;    // garments only
};

// Dresses a body: rest_full = all 19158 hm08 vertices (mm), body_F the skin triangles
// (MakeHuman::body_faces), W the weights of all vertices (MakeHuman::weights), pose = the bone
// maps or nullptr for the rest pose. The body part keeps only its visible faces and the vertices
// they use. Proxies (.proxy) are refused: they replace the body rather than dress it.
std::vector<DressedPart> dress_body(const Eigen::MatrixX3d& rest_full, const Eigen::MatrixX3i& body_F,
                                    const SkinWeights& W, const BoneTransforms* pose,
                                    const std::vector<Asset>& outfit, const DressOptions& options = {});

// Weights of each point (#P by 3) from its closest point on the body surface (V, F; W the rows
// of V): the closest triangle's rows mixed by the barycentric coordinates. `distance` (optional)
// receives each point's distance to the surface (mm).
SkinWeights skin_weights_at(const Eigen::MatrixX3d& P, const Eigen::MatrixX3d& body_V, const Eigen::MatrixX3i& body_F,
                            const SkinWeights& W, Eigen::VectorXd* distance = nullptr);

// A character of the statistical model (skin only: skin_rest the 13380 hm08 skin vertices, mm,
// skin_F its faces, skin_W its weights) dressed at rest: the helpers the assets are bound to
// rebuilt by the regressor (positions) and the tie (weights: each helper takes its skin
// triangle's rows mixed by its barycentric coordinates), then dress_body. `hidden` flags the
// skin vertices the outfit hides (#skin).
struct DressedSkinBody {
  std::vector<DressedPart> parts;
  std::vector<char> hidden;
  // All 19158 rows as the assets were fitted: positions, weights (skin, then each helper's skin
  // triangle's) and the vertices the outfit hides, for fitting more assets (proxies, assets/lod.h).
  Eigen::MatrixX3d full_rest;
  SkinWeights full_weights;
  std::vector<char> full_hidden;
};
DressedSkinBody dress_skin_body(const Eigen::MatrixX3d& skin_rest, const Eigen::MatrixX3i& skin_F,
                                const SkinWeights& skin_W, const HelperRegressor& regressor,
                                const HelperBinding& tie, const std::vector<Asset>& outfit,
                                const DressOptions& options = {});

// Body-through-cloth penetration over a clip as a skinned glb plays it: per frame, the body
// (skin_rest posed by linear blend skinning with skin_W) and each garment of `parts` (dressed at
// rest, posed with its carried weights), penetration_of at depth_mm.
struct ClipPenetration {
  std::vector<std::string> garments;
  Eigen::MatrixXd fraction, max_depth_mm;   // #frames by #garments
  // Frames where some garment has more than `limit` of its vertices deeper than depth_mm.
  int frames_over(double limit) const;
};
struct ClipCorrections;
ClipPenetration clip_penetration(const std::vector<DressedPart>& parts, const Eigen::MatrixX3d& skin_rest,
                                 const Eigen::MatrixX3i& skin_F, const SkinWeights& skin_W,
                                 const std::vector<char>& hidden, const std::vector<BoneTransforms>& frames,
                                 double depth_mm = 2.0, const ClipCorrections* corrections = nullptr);

// Per-frame garment corrections (docs/assets.md#penetration), what a skinned glb can play as
// morph targets: in each frame every garment, posed as the glb plays it, is pushed out of the
// posed body (push_garment_out, as at rest) when some vertex over visible skin is deeper than
// depth_mm, and each moved vertex's posed displacement c is taken back to bind space through its
// blended skinning transform, d = (Σ_j w_j R_j)⁻¹ c. Linear blend skinning is affine per vertex,
// so skinning V + d gives exactly the pushed positions at that frame; between frames a player
// blends the neighbouring corrections (not measured). A vertex whose blended transform is
// near-singular (|det| < 0.1, opposite rotations blended) is left uncorrected.
struct GarmentCorrection {
  int part = 0;               // index into the parts
  std::vector<int> vertex;    // rows of that part, increasing
  Eigen::MatrixX3d delta;     // bind-space displacement (mm), one row per vertex
};
struct ClipCorrections {
  std::vector<std::vector<GarmentCorrection>> frames;  // per frame: the garments corrected
  ClipPenetration uncorrected;   // clip_penetration without the corrections (measured on the way)
  int garment_frames = 0;        // corrected garment-frames
  long long vertices = 0;        // stored displacements over all frames
};
struct ClipCorrectionOptions {
  PushOutOptions push;           // as at rest: 1 mm clearance
  double depth_mm = 2.0;         // a garment-frame is corrected when a vertex is deeper than this
  double min_move_mm = 0.001;    // smaller displacements are not stored
};
// Arguments as clip_penetration's.
ClipCorrections clip_corrections(const std::vector<DressedPart>& parts, const Eigen::MatrixX3d& skin_rest,
                                 const Eigen::MatrixX3i& skin_F, const SkinWeights& skin_W,
                                 const std::vector<char>& hidden, const std::vector<BoneTransforms>& frames,
                                 const ClipCorrectionOptions& options = {});

// Between keys (docs/assets.md#between-keys-and-levels): the pose a glTF player shows at fraction
// s ∈ [0, 1] from key a to key b of a clip written by skinning/gltf_export.h (rest joint frames
// without rotation): each joint's local rotation (Q_parentᵀ Q) slerped and its local translation
// (Q_parentᵀ (M(h) − M_parent(h_parent))) interpolated linearly, then composed down the chain.
BoneTransforms pose_between_keys(const Skeleton& skeleton, const BoneTransforms& a, const BoneTransforms& b, double s);

// The corrections a player blends at fraction s from key f to key f + 1: the `weights` channel
// is LINEAR, so (1 − s) of key f's target and s of key f + 1's. One entry per interval
// (#frames − 1), for clip_penetration over the poses pose_between_keys gives.
ClipCorrections corrections_between_keys(const ClipCorrections& c, double s);

// A clip's corrections sampled finer than its keys where a player's blend of two neighbouring
// samples leaves the body through a garment (docs/assets.md#between-keys-and-levels). Times are in
// keys (key f at f); every key is a sample, and an interval whose half-way point (the pose
// pose_between_keys gives, the two samples' corrections blended half and half) has a garment over
// `limit` at depth_mm is halved: a sample is added there with the corrections clip_corrections
// makes for that pose, and its two halves are measured in turn, at most `max_halvings` times.
struct SampledCorrections {
  std::vector<double> times;       // increasing; the keys 0 … #frames − 1 and the samples added
  ClipCorrections corrections;     // corrections.frames[i] at times[i]; uncorrected: at the keys
  ClipPenetration between;         // half-way between consecutive samples as played (#times − 1 rows)
  ClipPenetration between_keys;    // half-way between the keys before any sample was added (#keys − 1)
  int added = 0;                   // samples added between keys
};
struct RefineOptions {
  ClipCorrectionOptions correction;   // as at the keys
  double limit = 0.01;                // a half-way point is over with more than this fraction over depth_mm
  int max_halvings = 3;               // per interval between keys: at most 2^3 − 1 samples added
};
// The pose a player shows at time t (in keys) of the clip `frames`.
BoneTransforms pose_at(const Skeleton& skeleton, const std::vector<BoneTransforms>& frames, double t);
// Arguments as clip_corrections', with the skeleton the frames pose and at_keys = clip_corrections
// of the frames. max_halvings 0 measures half-way between the keys and adds nothing.
SampledCorrections refine_between_keys(const std::vector<DressedPart>& parts, const Eigen::MatrixX3d& skin_rest,
                                       const Eigen::MatrixX3i& skin_F, const SkinWeights& skin_W,
                                       const std::vector<char>& hidden, const Skeleton& skeleton,
                                       const std::vector<BoneTransforms>& frames, const ClipCorrections& at_keys,
                                       const RefineOptions& options = {});

}  // namespace bodymodel
