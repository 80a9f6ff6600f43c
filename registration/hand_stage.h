// The hand stage of the pose fit (docs/pose_fit.md#hand-stage): after the body stage, the late
// parameters (finger curls, thumbs) and with them the wrists and forearm twists are fitted to the
// hand's own scan points with the rest of the body held, from several starts
// (docs/pose_fit.md#hand-starts), then each hand parameter is accepted only where it brings the
// hand closer to the scan.
#pragma once

#include "core/progress.h"
#include "registration/pose_fit_options.h"
#include "registration/pose_parameters.h"
#include "registration/pose_problem.h"

namespace bodymodel {

// Runs the hand stage on `unknowns`, changing only the hand parameters; does nothing without late
// parameters, hand samples or PoseFitOptions::hand_iterations. Fills the hand fields of
// `summary` (hand_iterations, hand_rms, hand_accept_*, hand_reverted, hand_start_*).
void run_hand_stage(const PoseProblem& problem, PoseUnknowns& unknowns, PoseFitSummary& summary,
                    const ProgressCallback& progress);

}  // namespace bodymodel
