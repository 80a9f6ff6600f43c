#include "tools/pipeline/registration_setup.h"

#include "core/makehuman.h"

namespace bodymodel {

RegistrationSetup makehuman_registration_setup(const RegistrationFlags& flags) {
  MakeHuman mh = MakeHuman::load();
  MakeHuman::Body body = mh.body(MacroSettings{});
  RegistrationSetup s{RegistrationTemplate{body.mesh, body.skeleton, body.weights, {}, {}}, {}};
  if (!flags.no_shape_fit) s.tpl.shape_space = std::move(mh);
  RegistrationOptions& o = s.options;
  o.nonrigid.schedule = flags.schedule == "paper" ? NonrigidSchedule::paper : NonrigidSchedule::fast;
  o.nonrigid.fast_steps = flags.fast_steps;
  o.nonrigid.fast_k_end = flags.fast_k_end;
  o.skip_nonrigid = flags.pose_only;
  o.fit_proportions = !flags.no_proportions;
  // Only read when the template has a shape space, i.e. when it is true.
  o.fit_shape = !flags.no_shape_fit;
  return s;
}

}  // namespace bodymodel
