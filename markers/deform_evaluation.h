// Park & Hodgins' marker-driven skin (markers/deform.h) on a capture with a truth mesh sequence,
// beside SSD and MWE rigs driven by a skeleton fitted to the same markers (issue 38).
//
// The mesh frames are split: every other one (0, 2, 4, …) trains, the others are held out. The
// training frames stand in for the paper's range-of-motion session:
//  - parts: the mesh's rigid sections recovered from the training frames (James & Twigg via
//    skinning/bone_recovery.h; the paper clustered the marker surface the same way, then adjusted
//    the parts by hand into 17);
//  - skeleton: per frame, each part's rigid map (reference → frame) fitted by least squares
//    (Kabsch) to its markers: the markers whose nearest reference vertex is in the part (at least
//    min_members, the nearest to the part's vertices when too few);
//  - SSD weights fitted to the training meshes with that skeleton (skinning/fit_lbs.h), and an MWE
//    rig over them (skinning/fit_mwe.h);
//  - Park's part weights of the vertices are the SSD weights, and a marker's those of its nearest
//    reference vertex (the paper interpolates marker weights, found from the markers' motion, onto
//    the vertices: the other direction).
// On the held-out frames every method is driven by the markers of that frame only, and compared
// with the truth mesh: mean and max vertex distance.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/progress.h"
#include "core/skeleton.h"
#include "markers/clean.h"
#include "markers/deform.h"
#include "markers/marker_data.h"
#include "skinning/skinning_rig.h"

namespace bodymodel {

struct MarkerDeformOptions {
  MarkerSkinOptions skin;
  int parts = 17;                     // rigid parts (the paper's 17)
  double mesh_rate = 10;              // frames per second of the meshes; the capture's rate is the markers'
  double max_marker_distance = 50;    // reference marker to nearest reference vertex (the markers' unit)
  int max_influences = 4;             // SSD slots per vertex
  int weight_markers = 0;             // Park's vertex weights: from this many nearest markers (0: the SSD weights)
  unsigned seed = 1;
  // Frames × markers in (0, 1] (filled_sample_confidence), or empty: every sample trusted (the
  // paper). Weighs the samples in Park's fits and in the rigs' skeleton (the same for all methods).
  Eigen::MatrixXd confidence;
};

// The confidence of each sample of a cleaned capture (frames × markers): 1 where the marker was
// seen; in a gap the cleaning filled (`gaps`: CleanReport::gaps), filled_weight · 2^(−(d − 1) /
// halflife), d the frames to the nearest sample seen (1 next to one): a filled sample's error grows
// with the time since the marker was seen (docs/markers.md#confidence-of-filled-samples).
// InputError (one line) for a gap of an unknown marker or outside the frames, a weight outside
// (0, 1] or a half-life not positive.
Eigen::MatrixXd filled_sample_confidence(const MarkerData& d, const std::vector<GapRecord>& gaps, double filled_weight,
                                         double halflife);

struct MethodError {
  std::string method;
  double mean = 0, max = 0;            // vertex distance over the held-out frames (the markers' unit)
  std::vector<double> frame_mean;      // per held-out frame
};

struct MarkerDeformComparison {
  MarkerSkin skin;                      // Park & Hodgins' model, ready for deform_by_markers
  SkinningRig ssd, mwe;
  std::vector<std::vector<int>> part_markers;  // the skeleton's markers per part
  std::vector<int> train_meshes, test_meshes;  // mesh frame indices
  std::vector<int> test_frames;                // the capture frames of test_meshes
  std::vector<MethodError> errors;             // park (full), park-quadratic, park-rigid, ssd, mwe
  int frames_per_mesh = 1;
};

// Rigid maps reference → frame of each part from its markers (Kabsch, refitted without the outliers
// as Park's parts are: o.outlier_factor, o.outlier_floor × the markers' RMS radius), as a skeleton.
// confidence: #M (empty: all 1), weighing each marker in the fits.
BoneTransforms fit_marker_skeleton(const Eigen::MatrixX3d& reference, const Eigen::MatrixX3d& markers,
                                   const std::vector<std::vector<int>>& part_markers, const MarkerSkinOptions& o = {},
                                   const Eigen::VectorXd& confidence = Eigen::VectorXd());

// The markers of one frame as #M by 3.
Eigen::MatrixX3d marker_frame(const MarkerData& d, int frame);

// meshes: the truth sequence (same faces F), already in the markers' unit; frame 0 is the
// reference pose and the mesh driven. markers: labelled, complete (a cleaned capture), capture
// frame f at mesh time f · mesh_rate / rate. InputError (one line) when: there are unlabelled
// pieces or missing samples, the capture rate is not a whole multiple of the mesh rate, the frame
// counts disagree, fewer than 3 meshes, or a reference marker is farther than max_marker_distance
// from the reference mesh (markers of another mesh, or in another unit), or options.confidence is
// not empty and not frames × markers in (0, 1].
MarkerDeformComparison compare_marker_skins(const std::vector<Eigen::MatrixX3d>& meshes, const Eigen::MatrixX3i& F,
                                            const MarkerData& markers, const MarkerDeformOptions& options = {},
                                            const ProgressCallback& progress = {});

}  // namespace bodymodel
