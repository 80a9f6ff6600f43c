// One MakeHuman load per test binary, shared by every test that needs the body model.
#pragma once

#include "core/makehuman.h"

namespace bodymodel {

// The default loader (defective height targets substituted).
inline const MakeHuman& shared_makehuman() {
  static const MakeHuman mh = MakeHuman::load();
  return mh;
}

// A raw loader (upstream data exactly as shipped, README §10.1).
inline const MakeHuman& shared_makehuman_raw() {
  static const MakeHuman mh = [] {
    MakeHuman::Options o;
    o.substitute_defective_height_targets = false;
    return shared_makehuman().with_options(o);
  }();
  return mh;
}

}  // namespace bodymodel
