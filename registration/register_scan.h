// The whole registration of one scan (Hasler et al. 2009 §2): scan checks, skeleton-based pose
// estimation (§2.2), then non-rigid registration (§2.3) started from the posed template.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/progress.h"
#include "core/skeleton.h"
#include "registration/landmarks.h"
#include "registration/nonrigid.h"
#include "registration/pose_fit.h"
#include "registration/proportions.h"
#include "registration/scan.h"

namespace bodymodel {

// The template: rest mesh (mm), skeleton and LBS weights (e.g. the MakeHuman default body).
struct RegistrationTemplate {
  Mesh mesh;
  Skeleton skeleton;
  SkinWeights weights;
};

struct RegistrationOptions {
  ScanCheckOptions scan;
  PoseFitOptions pose;
  NonrigidOptions nonrigid;
  // Stretch the template's segments to the landmarks' proportions before the pose fit
  // (registration/proportions.h); needs ≥ 3 landmarks.
  bool fit_proportions = true;
  ProportionOptions proportions;
  bool skip_nonrigid = false;  // stop after the pose fit
};

struct RegistrationSummary {
  ScanCheckReport scan;
  PoseFitSummary pose;
  NonrigidSummary nonrigid;
  double seconds = 0.0;
};

struct RegistrationResult {
  Eigen::MatrixX3d V;     // #V by 3 registered template vertices (template topology, mm)
  PoseFitResult pose;     // scale, joint rotations and the posed template
  Proportions proportions;  // segment ratios applied to the template (empty if none)
};

// Registers `scan` (modified: normals checked/estimated) with `landmarks` (template vertex →
// scan position). `what` names the scan in error messages.
RegistrationResult register_scan(const RegistrationTemplate& tpl, PointCloud& scan,
                                 const std::vector<Landmark>& landmarks,
                                 const RegistrationOptions& options, const std::string& what,
                                 RegistrationSummary* summary = nullptr,
                                 const ProgressCallback& progress = {});

}  // namespace bodymodel
