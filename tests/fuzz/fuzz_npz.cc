#include "core/io/npz.h"
#include "fuzz_common.h"
BODYMODEL_FUZZ_TARGET({
  bodymodel::Npz z = bodymodel::Npz::parse(input, "fuzz.npz");
  for (auto& k : z.keys()) {
    try { z.matrix(k); } catch (const bodymodel::InputError&) {}
    try { z.text(k); } catch (const bodymodel::InputError&) {}
  }
})
