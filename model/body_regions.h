// Body-region masks for selective morphing (Hasler et al. 2009 §5.1, Fig. 6) from the model's
// skinning weights: a vertex's mask value is the total weight of the region's bones.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "model/model_rig.h"

namespace bodymodel {

// Region names: arms, legs, torso, head, left_arm, right_arm, left_leg, right_leg.
std::vector<std::string> body_region_names();
// #V vertex mask in [0, 1]. InputError listing the regions for an unknown name, or when the
// rig is empty.
Eigen::VectorXd body_region_vertex_mask(const ModelRig& rig, const std::string& region);

}  // namespace bodymodel
