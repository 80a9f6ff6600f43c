// Cleaning a dense-marker capture (Park & Hodgins 2006, section 4): the labelled markers (names
// not starting with '*', all present in the reference frame) define the marker surface; the
// unlabelled pieces ("*1", "*2", …) are merged into the marker whose position, estimated from its
// visible neighbours by a rigid fit in the reference frame, they follow (eq. 2–3: within
// a1 · the mean neighbour distance at the piece's first frame, and a2 · it over the whole piece,
// never overlapping the marker's own samples); holes are filled from a PCA model of each marker's
// neighbourhood in its local frame, fitted to the neighbours present (averaged over the models
// of the marker and of its neighbours, and with its rigid part's or neighbours' rigid motion from the
// nearest frames where the marker was seen); the trajectories are smoothed in the local frame. Pieces left are
// matched again against the filled trajectories (`rounds`), and the holes filled again. A merged
// piece the marker's neighbourhood models (fitted on the merged data, the piece's own sample left
// out of each estimate) put farther than model_tolerance · spacing is taken out again. The pieces
// still left are then matched by those models alone (`model_rounds`). Rigid parts found from the
// capture itself (markers whose mutual distances stay nearly fixed) predict a missing marker beside
// its one-ring, and place each long piece left in the reference frame by the markers moving with it,
// which names its marker (`part_rounds`). Every merge is checked against the distances from the
// marker to its part's members: a piece that keeps another nearby missing marker's part distances
// `ambiguity` times better is refused, and a short piece far from them all (a ghost) taken out (`part_check`).
// Approximations: the marker surface's one-ring is the k nearest markers in the reference frame
// (the paper built it by hand); frames with fewer than 3 visible neighbours, after a second pass
// that lets filled neighbours count, are filled by linear interpolation in time (reported apart).
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "markers/marker_data.h"

namespace bodymodel {

struct CleanOptions {
  int reference_frame = 0;
  int neighbours = 6;                 // the one-ring: nearest markers in the reference frame
  double merge_tolerance = 0.5;       // a1 of the paper
  double piece_tolerance = 0.6;       // a2 of the paper
  double ambiguity = 2;               // a piece another marker explains within this factor stays unmerged
  double rigidity = 0.1;              // a neighbour's distance may vary by this fraction of itself (std over time)
  double part_rigidity = 9;           // mm: markers whose distance varies less (std over time) share a rigid part (0 = no parts)
  double piece_rigidity = 15;         // mm: the same for a piece and the markers moving with it (longer: looser)
  int part_size = 10;                 // a marker's rigid part: at most this many of its nearest markers
  int part_rounds = 2;                // rounds matching the pieces left by their own rigid part (0 = none)
  double part_check = 3;              // merges checked against the part's distances (0 = off); a short piece this · part_rigidity off is a ghost
  int min_piece = 1;                  // shorter pieces are left unmerged (too short to tell whose they are)
  int rounds = 2;                     // merges against the filled trajectories (then filled again)
  double model_tolerance = 0.35;      // a merge its neighbourhood models put farther than this · spacing is undone (0 = never)
  int model_rounds = 1;               // then pieces left are matched by the neighbourhood models alone (0 = none)
  double pca_energy = 0.99;           // variance kept by each neighbourhood's model
  int smooth_iterations = 2;          // passes of the local-frame smoothing (0 = none)
  double smooth_lambda = 0.25;
};

struct MergeRecord {
  std::string piece, marker;
  int first = 0, last = 0;      // frames (0-based)
  double mean_distance_mm = 0;  // from the neighbours' estimate
};

// A run of missing samples of one marker after merging (frames 0-based, inclusive): what the
// hole filling filled (or, when no sample bounds it on one side, held).
struct GapRecord {
  std::string marker;
  int first = 0, last = 0;
};

struct CleanReport {
  int markers = 0, pieces = 0, merged = 0;
  std::vector<MergeRecord> merges;
  std::vector<std::string> unmerged;  // pieces left (ghosts, or pieces no marker explained)
  std::vector<MergeRecord> undone;    // merges taken out again (mean_distance_mm: from the neighbourhood models)
  int gaps_before = 0, gaps_after_merge = 0, gaps_filled = 0, gaps_left = 0;
  long samples_missing = 0, filled_from_neighbours = 0, filled_by_interpolation = 0;
  std::vector<GapRecord> gaps;        // the gaps found (after merging), in marker then frame order
};

struct CleanResult {
  MarkerData merged;   // the labelled markers after merging, holes still NaN
  MarkerData cleaned;  // every labelled marker at every frame (filled, smoothed)
  CleanReport report;
};

// InputError when there are no labelled markers, fewer than neighbours + 1 of them, or a labelled
// marker is missing in the reference frame.
CleanResult clean_markers(const MarkerData& capture, const CleanOptions& options = {},
                          const std::function<void(double)>& progress = {});

// The runs of missing samples of every marker of `d`, in marker then frame order.
std::vector<GapRecord> find_gaps(const MarkerData& d);

nlohmann::json clean_report_json(const CleanReport& r);
std::string clean_summary_line(const CleanReport& r);

// Against the truth (every marker at every frame, the same labels): wrong merges (a merged piece
// farther than 10 mm on average from the marker's truth), pieces of a marker left unmerged, and
// the error of the filled samples, beside a natural cubic spline through the same marker's
// samples over the same holes (holes between two samples only: a spline does not extrapolate).
struct CleanEvaluation {
  int wrong_merges = 0, missed_pieces = 0;
  long filled = 0, interior_filled = 0;
  double median_fill_mm = 0, mean_fill_mm = 0, p95_fill_mm = 0;
  double median_interior_mm = 0, median_spline_mm = 0;  // the same interior holes
  double ratio_to_spline = 0;                           // median_interior / median_spline
  long gap_5_60 = 0;                                    // interior holes of 5–60 frames (the issue's)
  double median_5_60_mm = 0, median_spline_5_60_mm = 0, ratio_5_60 = 0;
};
CleanEvaluation evaluate_cleaning(const MarkerData& capture, const CleanResult& result, const MarkerData& truth);
nlohmann::json evaluation_json(const CleanEvaluation& e);

// Natural cubic spline through the samples present in `x` (one coordinate, NaN = missing),
// evaluated at every frame between the first and the last sample (NaN outside).
Eigen::VectorXd spline_fill(const Eigen::VectorXd& x);

}  // namespace bodymodel
