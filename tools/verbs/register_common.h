// The flags `register` and `register-mesh` share, bound to one RegistrationJobOptions
// (registration/job.h), so both verbs name, document and default them alike.
#pragma once

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "core/io/shape_space_file.h"
#include "core/makehuman.h"
#include "model/model_file.h"
#include "model/model_shape_space.h"
#include "registration/job.h"
#include "tools/console.h"
#include "tools/pipeline/folder_settings.h"

namespace bodymodel::cli {

// The inverse flags (--no-*) are kept in `no` and applied by apply_registration_flags.
struct NegatedRegistrationFlags {
  bool no_proportions = false, no_shape_fit = false;
  std::string shape_space;  // --shape-space FILE, read by apply_registration_flags
  std::string model;        // --model FILE, read and linearised by apply_registration_flags
  int model_components = 20;
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
  cmd->add_option("--landmark-floor", job.landmark_floor,
                  "Smallest landmark weight γ of the non-rigid fit (γ = 2β otherwise falls with the stiffness β, "
                  "and the landmarks then weigh as little as two data points)")
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
  cmd->add_option("--model", no.model,
                  "Fit the shape in the SHAPE space of a model built by `bodymodel build` from registrations (MakeHuman "
                  "topology), its variances as the prior, instead of the macro sliders; the template starts as its "
                  "mean body. The space is linearised around the mean (docs/real-registration.md)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--model-components", no.model_components,
                  "With --model: its leading shape components fitted (-1: all)")
      ->capture_default_str();
  cmd->add_option("--model-prior", job.model_space_prior,
                  "With --model: the prior's weight (mm² of mean squared scan distance that one standard deviation "
                  "costs)")
      ->capture_default_str();
}

// The model's shape space, linearised around its mean in MakeHuman's frame (a one-line InputError
// naming the file when it is not a model of MakeHuman's topology).
inline std::shared_ptr<const VertexShapeSpace> read_model_shape_space(const std::string& path, int components) {
  BodyModel model;
  try {
    model = load_model(path);
  } catch (const InputError& e) {
    throw InputError(std::string("--model: ") + e.what());  // names the file
  } catch (const std::exception& e) {
    throw InputError("--model '" + path + "': not a readable model (" + e.what() + ")");
  }
  ModelShapeSpaceOptions o;
  o.components = components;
  o.frame = MakeHuman::load().body(MacroSettings{}).mesh.V;
  o.measure_error = true;  // 2 more decodes per component: the user sees what the approximation costs
  ModelShapeSpaceSummary s;
  VertexShapeSpace space;
  try {
    space = model_shape_space(model, o, &s);
  } catch (const InputError& e) {
    throw InputError("--model '" + path + "': " + e.what());
  }
  space.source = path + ": " + space.source;
  info(fmt::format("--model: {} ({} decodes, {:.1f} s); at ±{} sd, where a vertex moves up to {:.0f} mm, the "
                   "approximate body is {:.2f} mm (mean) / {:.1f} mm (max) from the exact decode (first order alone: "
                   "{:.2f} / {:.1f} mm)",
                   space.source, s.decodes, s.seconds, o.error_at_sd, s.max_displacement_mm, s.mean_error_mm,
                   s.max_error_mm, s.mean_error_linear_mm, s.max_error_linear_mm));
  return std::make_shared<const VertexShapeSpace>(std::move(space));
}

inline void apply_registration_flags(RegistrationJobOptions& job, const NegatedRegistrationFlags& no) {
  job.proportions = !no.no_proportions;
  job.shape_fit = !no.no_shape_fit;
  if (!no.shape_space.empty()) job.learned_space = std::make_shared<const ShapeSpace>(read_shape_space(no.shape_space));
  if (!no.model.empty()) {
    if (!no.shape_space.empty()) throw InputError("--shape-space and --model: give one shape space");
    job.model_space = read_model_shape_space(no.model, no.model_components);
  }
}


// The resumable folder's settings both registration verbs share; each is recorded only when
// given or on, so folders made before the option resume as they were.
inline void add_shared_registration_settings(nlohmann::json& settings, const RegistrationJobOptions& job,
                                             const NegatedRegistrationFlags& no) {
  if (job.contact_segments) settings["contact_segments"] = true;
  if (job.landmark_floor > 0) settings["landmark_floor"] = job.landmark_floor;
  if (!no.shape_space.empty()) {
    settings["shape_space"] = file_fingerprint(no.shape_space);
    settings["shape_space_prior"] = job.learned_space_prior;
  }
  if (!no.model.empty()) {
    settings["model"] = file_fingerprint(no.model);
    settings["model_components"] = no.model_components;
    settings["model_prior"] = job.model_space_prior;
  }
}

}  // namespace bodymodel::cli
