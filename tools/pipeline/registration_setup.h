// The template and options that `register` and `register-mesh` share: MakeHuman's default body
// as the template (with MakeHuman as its shape space unless the shape fit is off) and the
// registration options both verbs set from the same flags. Each verb adds its own options
// (pose parameters, hand stage, transform length, pose iterations) to the result.
#pragma once

#include <string>

#include "registration/register_scan.h"

namespace bodymodel {

struct RegistrationFlags {
  std::string schedule = "fast";  // --schedule: "paper" or "fast"
  int fast_steps = NonrigidOptions{}.fast_steps;
  double fast_k_end = NonrigidOptions{}.fast_k_end;
  bool pose_only = false;       // --pose-only: stop after the pose fit
  bool no_proportions = false;  // --no-proportions
  bool no_shape_fit = false;    // --no-shape-fit: no MakeHuman shape space on the template
};

struct RegistrationSetup {
  RegistrationTemplate tpl;
  RegistrationOptions options;
};

// Loads MakeHuman (throws as MakeHuman::load does when its data is missing).
RegistrationSetup makehuman_registration_setup(const RegistrationFlags& flags);

}  // namespace bodymodel
