// The flags `register` and `register-mesh` share, bound to one RegistrationJobOptions
// (registration/job.h), so both verbs name, document and default them alike.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>

#include "registration/job.h"

namespace bodymodel::cli {

// The inverse flags (--no-*) are kept in `no` and applied by apply_registration_flags.
struct NegatedRegistrationFlags {
  bool no_proportions = false, no_shape_fit = false;
};

inline void add_registration_flags(CLI::App* cmd, RegistrationJobOptions& job, NegatedRegistrationFlags& no) {
  cmd->add_option("--schedule", job.schedule,
                  "Non-rigid stiffness schedule: 'paper' (1500 steps, §2.3) or 'fast'")
      ->check(CLI::IsMember({"paper", "fast"}))
      ->capture_default_str();
  cmd->add_option("--fast-steps", job.fast_steps, "Steps of the fast schedule")->capture_default_str();
  cmd->add_option("--fast-stiffness-end", job.fast_k_end,
                  "Final smoothness weight β of the fast schedule (starts at k0 = 3000)")
      ->capture_default_str();
  cmd->add_flag("--pose-only", job.pose_only, "Stop after the skeleton pose fit");
  cmd->add_flag("--no-proportions", no.no_proportions,
                "Keep the template's limb proportions (global scale only) instead of stretching "
                "its segments to the landmark distances");
  cmd->add_flag("--no-shape-fit", no.no_shape_fit,
                "Keep the default MakeHuman body's shape (global scale and landmark proportions "
                "only) instead of fitting the macro sliders (gender, age, muscle, weight, "
                "height, proportions, cup) in the pose stage");
}

inline void apply_registration_flags(RegistrationJobOptions& job, const NegatedRegistrationFlags& no) {
  job.proportions = !no.no_proportions;
  job.shape_fit = !no.no_shape_fit;
}

}  // namespace bodymodel::cli
