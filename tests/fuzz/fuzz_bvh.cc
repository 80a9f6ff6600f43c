#include "core/io/bvh.h"
#include "fuzz_common.h"
BODYMODEL_FUZZ_TARGET({
  bodymodel::BvhMotion m = bodymodel::parse_bvh(input, "fuzz.bvh");
  m.rest_positions();
  for (int f = 0; f < std::min(m.frame_count(), 3); ++f)
    for (int j = 0; j < static_cast<int>(m.joints.size()); ++j) bodymodel::bvh_joint_rotation(m, f, j);
})
