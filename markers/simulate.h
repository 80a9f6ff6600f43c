// A realistic dense-marker capture simulated from a mesh sequence with truth (Park & Hodgins
// 2006 use ~350 markers 4–5 cm apart): markers placed on the first frame by farthest-point
// sampling of the surface, offset by their radius along the normal and carried through the frames
// by barycentric coordinates; a ring of cameras decides what is seen (a marker needs two cameras
// that it faces and whose line of sight the body does not block), plus random gaps up to a
// target missing fraction, 1 mm noise, trajectories broken into unlabelled pieces ("*1", "*2", …,
// the Vicon convention) after every gap and where a neighbour passes closest, and ghost markers.
// Approximations (documented in docs/markers.md): the mesh frames are interpolated in time
// (Catmull-Rom) up to the capture rate; the reference frame (frame 0) is complete, as the paper
// assumes.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "markers/marker_data.h"

namespace bodymodel {

struct SimulateOptions {
  int markers = 350;
  double marker_radius_mm = 5;
  double mm_per_unit = 1000;   // mesh units to mm (the Vlasic captures are in metres)
  double mesh_rate = 10;       // frames per second of the given meshes
  double rate = 120;           // capture rate (frames per second)
  int cameras = 8;
  double camera_distance_mm = 4000, camera_height_mm = 2200;
  double max_view_angle_deg = 75;  // a marker facing a camera more obliquely is not seen by it
  double noise_mm = 1;             // standard deviation per coordinate
  double missing = 0.15;           // target fraction of missing samples (occlusion, then random gaps)
  int gap_min = 5, gap_max = 60;   // frames, the random gaps
  double broken = 0.05;            // fraction of markers whose trajectory breaks where a neighbour passes closest
  int ghosts = 5;                  // short spurious trajectories
  unsigned seed = 1;
};

// Which marker each unlabelled piece of the capture belongs to.
struct PieceTruth {
  std::string label;
  int marker = -1;  // index into truth.labels; -1: a ghost
  int first = 0, last = 0;
};

struct SimulatedCapture {
  MarkerData capture;  // labelled pieces (holding frame 0), then the pieces "*k", then ghosts
  MarkerData truth;    // every marker at every frame, without noise
  std::vector<PieceTruth> pieces;
  double occluded = 0;      // fraction of samples the cameras did not see
  double missing = 0;       // fraction missing in the end (labelled markers, occlusion + gaps)
  int random_gaps = 0, broken = 0;
  double spacing_mm = 0;    // median distance from a marker to its nearest neighbour (frame 0)
};

// frames: the mesh sequence (same faces F), in mesh units, +y up. progress(fraction) is called
// as frames are done (may be empty).
SimulatedCapture simulate_capture(const std::vector<Eigen::MatrixX3d>& frames, const Eigen::MatrixX3i& F,
                                  const SimulateOptions& options,
                                  const std::function<void(double)>& progress = {});

}  // namespace bodymodel
