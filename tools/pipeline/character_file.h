// The character rig file `char/rig.npz`: a skinning rig file (skinning/rig_io.h keys, the MWE
// rig) plus what animating it needs — the skeleton placed in the body, the fitted SSD rig and
// the template's SSD weights for comparison, and a description of the character. numpy opens it.
// Extra keys:
//   skeleton_names       JSON text: #B bone names
//   skeleton_parents     #B int, −1 for the root
//   skeleton_heads/tails #B by 3, mm
//   skeleton_driven      #B int, 1 = the rig was trained with this bone moving; animation sets
//                        the others' rotations to identity (tools/pipeline/character.h)
//   lbs_influences, lbs_coefficients            #V by K, the SSD rig the MWE refines (smoothed
//                                               template weights, CharacterOptions)
//   template_influences, template_coefficients  #V by K, the model's weights (largest K)
//   character            JSON text: how the body was made, measured labels, fit errors
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <vector>

#include "core/skeleton.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

struct CharacterRigFile {
  SkinningRig rig;            // the MWE rig (or whatever method was saved)
  SkinningRig lbs;            // the SSD the MWE refines
  SkinningRig template_lbs;   // the model's weights
  Eigen::MatrixX3i F;         // #F by 3
  Skeleton skeleton;
  std::vector<char> driven;   // #B
  std::vector<BoneTransforms> training_transforms;
  nlohmann::json character;
};

// Writes atomically (InputError naming the file on failure).
void save_character_rig(const std::filesystem::path& path, const CharacterRigFile& c);
// InputError naming the file when it is not a character rig (e.g. a plain `skin fit` rig: no
// skeleton) or its arrays disagree.
CharacterRigFile load_character_rig(const std::filesystem::path& path);

}  // namespace bodymodel
