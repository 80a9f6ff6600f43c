// A body's skinning rig carried to an asset through its binding, so the asset is posed by the
// same method as the body: LBS (SSD), dual quaternions or Multi-Weight Enveloping.
//
// An asset vertex takes the coefficient rows of the body vertices its binding row reads, mixed
// by the row's weights (per bone: Σ_k w_k · coefficients of bone b at vertex v_k), with its own
// rest position. For MWE, whose coefficients multiply the rest position's entries, this is the
// body's deformation field near the asset sampled at the asset's own point. LBS and DQS weights
// drop negative mixes and are renormalised; MWE coefficients are mixed as they are. Animation
// Space rigs are refused (their coefficients embed each vertex's rest position, so a mix is not
// the asset's).
#pragma once

#include <Eigen/Core>

#include "assets/binding.h"
#include "assets/helpers.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

// The asset's rig: #A vertices at `asset_rest` (the asset fitted to the rig's rest body). The
// rig must cover every vertex the binding reads (19158 rows; extend a skin-only rig first).
SkinningRig carry_rig(const AssetBinding& binding, const SkinningRig& body_rig, const Eigen::MatrixX3d& asset_rest);

// A rig over the 13380 skin vertices extended to all 19158: each helper takes the rows of its
// skin triangle mixed by its barycentric coordinates (assets/helpers.h), at `full_rest`'s
// position (the rows of complete_with_helpers or MakeHuman::build_vertices).
SkinningRig extend_rig_to_helpers(const SkinningRig& skin_rig, const HelperBinding& helpers,
                                  const Eigen::MatrixX3d& full_rest);

}  // namespace bodymodel
