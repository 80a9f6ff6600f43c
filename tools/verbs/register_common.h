// The flags `register` and `register-mesh` share, bound to one RegistrationJobOptions
// (registration/job.h), so both verbs name, document and default them alike.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "core/io/shape_space_file.h"
#include "registration/job.h"

namespace bodymodel::cli {

// The inverse flags (--no-*) are kept in `no` and applied by apply_registration_flags.
struct NegatedRegistrationFlags {
  bool no_proportions = false, no_shape_fit = false;
  std::string shape_space;  // --shape-space FILE, read by apply_registration_flags
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
  cmd->add_flag("--contact-segments", job.contact_segments,
                "Refuse non-rigid data pairs between body segments that do not touch on the template (a scan "
                "point of a hand resting on a hip, of crossed forearms or of a foot on the other knee is then "
                "matched only to its own limb; docs/real-registration.md#contacts)");
  cmd->add_option("--shape-space", no.shape_space,
                  "Fit the shape in a space learned from real bodies (a file of `bodymodel shape-space`, "
                  "e.g. ANSUR II's soldiers) instead of the macro sliders; the template starts as its mean body")
      ->check(CLI::ExistingFile);
  cmd->add_option("--shape-space-prior", job.learned_space_prior,
                  "With --shape-space: the prior's weight (mm² of mean squared scan distance that one standard "
                  "deviation of the population costs; larger keeps bodies nearer the population's)")
      ->capture_default_str();
}

inline void apply_registration_flags(RegistrationJobOptions& job, const NegatedRegistrationFlags& no) {
  job.proportions = !no.no_proportions;
  job.shape_fit = !no.no_shape_fit;
  if (!no.shape_space.empty()) job.learned_space = std::make_shared<const ShapeSpace>(read_shape_space(no.shape_space));
}

}  // namespace bodymodel::cli
