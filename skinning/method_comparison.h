// `skin eval`'s protocol around evaluate_skinning_sequence (docs/skinning.md): which frames train
// and which stay unseen (one split or leave-one-out), the cross-validation scheme that suits the
// split, and every method's errors pooled over the folds. The verb and Python's
// `compare_skinning` call it; the verb only reads the frames and writes the tables.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/progress.h"
#include "skinning/sequence_evaluation.h"

namespace bodymodel {

// How to split frame_count frames; the first rule that is set wins: leave_one_out, train (frame
// indices, e.g. from --train), train_fraction (the first fraction), train_every (every k-th), else
// train_count evenly spaced frames (0: 10, leaving one unseen on short sequences).
struct FrameSplitRequest {
  bool leave_one_out = false;
  std::vector<int> train;
  bool explicit_test = false;  // train lists one side of an explicit split (--test names the other)
  double train_fraction = 0;
  int train_every = 0;
  int train_count = 0;
  int rest = -1;  // the rest frame; -1: frame 0 under leave-one-out, else the first training frame
  std::vector<std::string> frame_names;  // for the protocol text (frame indices when empty)
};

struct FrameSplit {
  std::vector<std::vector<int>> folds;  // training frames per fold
  std::string protocol;                 // how they were chosen, for the report
  int rest = 0;
  // Every unseen frame comes after every training frame (a forecast): cross-validation "auto"
  // then holds back the last training frames.
  bool forecast = false;
};

// InputError when the request leaves no unseen frame or names frames out of range.
FrameSplit split_frames(int frame_count, const FrameSplitRequest& request);

// "auto" (last training frames for a forecast, else interleaved folds), "none", "folds:K",
// "last:N" (N = 0: a third). InputError naming --cv otherwise.
SkinCrossValidationOptions parse_cv_scheme(const std::string& text, bool forecast);
std::string cv_description(const SkinCrossValidationOptions& options);

struct CvCandidateRow {
  size_t fold = 0;
  SkinningModel method;
  CvCandidate candidate;
  bool chosen = false;
  std::string chosen_by;  // the rules that would keep this candidate ("min one-se …")
};

struct SkinningComparison {
  std::vector<SkinningModel> methods;
  std::vector<DeviationStats> train, unseen;       // per method, pooled over the folds
  std::vector<Eigen::VectorXd> per_vertex_unseen;  // per method: #V mean unseen geometric error
  std::vector<std::vector<double>> frame_error;    // per method, per frame (unseen frames' own fold)
  std::vector<std::string> frame_split;            // per frame: "train" or "unseen"
  std::vector<double> fit_cpu;                     // per method, seconds of CPU over the folds
  std::vector<CvCandidateRow> cv_rows;
  SequenceEvaluation last;  // the last fold's evaluation (fits, bones, diagonal)
  double seconds = 0, prepare_cpu = 0, cv_setup_cpu = 0;
};

// InputError, before any work, when a method cannot be fitted on some fold
// (check_evaluation_request).
void check_comparison(int frame_count, const FrameSplit& split, SequenceEvaluationOptions options);

// Runs evaluate_skinning_sequence on every fold of `split` (options.rest_frame is set from it) and
// pools the results. Checks the request first (check_evaluation_request).
SkinningComparison compare_skinning_methods(const std::vector<Eigen::MatrixX3d>& frames, const Eigen::MatrixX3i& F,
                                            const FrameSplit& split, SequenceEvaluationOptions options,
                                            const ProgressCallback& progress = {});

}  // namespace bodymodel
