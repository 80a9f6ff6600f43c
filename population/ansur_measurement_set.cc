#include <memory>

#include "core/ansur_measure.h"
#include "population/ansur_fit.h"

namespace bodymodel {

MeasurementSet ansur_measurement_set(const MakeHuman& mh) {
  const MakeHuman::Body reference = mh.body(MacroSettings{});
  auto measurer = std::make_shared<const AnsurMeasurer>(mh.body_faces(), mh.body_weights(), reference.mesh.V,
                                                        mh.skeleton_from_body(reference.mesh.V));
  MeasurementSet set;
  set.names = AnsurMeasurer::names();
  set.measure = [measurer, mh](const Eigen::MatrixX3d& V) { return measurer->measure(V, mh.skeleton_from_body(V)); };
  return set;
}

}  // namespace bodymodel
