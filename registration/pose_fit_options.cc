#include "registration/pose_fit_options.h"

#include <cmath>
#include <sstream>

#include "core/error.h"

namespace bodymodel {

namespace {

// Throws InputError "pose fit: option NAME is VALUE, expected EXPECTED" unless ok.
void require(bool ok, const char* name, double value, const char* expected) {
  if (ok) return;
  std::ostringstream s;
  s << "pose fit: option " << name << " is " << value << ", expected " << expected;
  throw InputError(s.str());
}

void require_positive(const char* name, double v) {
  require(std::isfinite(v) && v > 0, name, v, "a positive number");
}
void require_non_negative(const char* name, double v) {
  require(std::isfinite(v) && v >= 0, name, v, "a number ≥ 0");
}
void require_fraction(const char* name, double v) {
  require(v >= 0 && v < 1, name, v, "a fraction in [0, 1)");
}
void require_finite(const char* name, double v) {
  require(std::isfinite(v), name, v, "a finite number");
}
void require_count(const char* name, int v, int min) {
  require(v >= min, name, v, min == 0 ? "a count ≥ 0" : "a count ≥ 1");
}

}  // namespace

void PoseFitOptions::validate() const {
  for (const PoseParameter& p : parameters)
    if (p.tuck && !p.late)
      throw InputError("pose fit: the tuck parameter of bone '" +
                       (p.bones.empty() ? std::string("?") : p.bones[0]) +
                       "' is not late (a tuck is set by the hand stage's starts)");
  require_finite("initial_scale", initial_scale);
  require_positive("max_distance", max_distance);
  require_positive("initial_max_distance", initial_max_distance);
  require(max_normal_angle_deg > 0 && max_normal_angle_deg <= 180, "max_normal_angle_deg",
          max_normal_angle_deg, "an angle in (0, 180] degrees");
  require_count("sample_vertices", sample_vertices, 1);
  require_positive("robust_scale", robust_scale);
  require_non_negative("point_to_point_weight", point_to_point_weight);
  require_non_negative("symmetric_weight", symmetric_weight);
  require_count("scan_samples", scan_samples, 1);
  require_fraction("trim_fraction", trim_fraction);
  require_count("landmark_rigid_depth", landmark_rigid_depth, 0);
  require_non_negative("landmark_weight", landmark_weight);
  require_count("landmark_iterations", landmark_iterations, 0);
  require_non_negative("pose_prior", pose_prior);
  require_non_negative("initial_prior_factor", initial_prior_factor);
  require_positive("landmark_prior_factor", landmark_prior_factor);
  require_non_negative("anchor_prior", anchor_prior);
  require_count("max_icp_iterations", max_icp_iterations, 0);
  require_count("solver_iterations", solver_iterations, 1);
  require_non_negative("convergence_deg", convergence_deg);
  require_non_negative("convergence_mm", convergence_mm);
  require_count("threads", threads, 1);
  require_count("hand_iterations", hand_iterations, 0);
  require_count("hand_sample_vertices", hand_sample_vertices, 1);
  require_positive("hand_initial_max_distance", hand_initial_max_distance);
  require_positive("hand_max_distance", hand_max_distance);
  require_non_negative("wrist_twist_prior", wrist_twist_prior);
  require_finite("curl_min_deg", curl_min_deg);
  require_finite("curl_max_deg", curl_max_deg);
  require_non_negative("finger_coupling", finger_coupling);
  require_finite("hand_accept_cap", hand_accept_cap);
  for (double v : hand_start_curls_deg) require_finite("hand_start_curls_deg", v);
  for (double v : hand_start_tucks_deg) require_finite("hand_start_tucks_deg", v);
  for (double v : hand_start_twists_deg) require_finite("hand_start_twists_deg", v);
  require_fraction("hand_start_margin", hand_start_margin);
  require_count("hand_start_align_steps", hand_start_align_steps, 0);
}

}  // namespace bodymodel
