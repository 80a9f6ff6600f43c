#include "core/io/mesh_io.h"
#include "fuzz_common.h"
BODYMODEL_FUZZ_TARGET(bodymodel::parse_mesh(input, "obj", "fuzz.obj"))
