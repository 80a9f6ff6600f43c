#include "core/io/mesh_io.h"
#include "fuzz_common.h"
BODYMODEL_FUZZ_TARGET({
  try {
    bodymodel::parse_mesh(input, "ply", "fuzz.ply");
  } catch (const bodymodel::InputError&) {
  }
  bodymodel::parse_ply_point_cloud(input, "fuzz.ply");
})
