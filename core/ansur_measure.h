// ANSUR II (US Army 2012) measurements on bodies with the hm08 template's topology (13 380
// vertices, mm, +y up, character's left = +x, facing +z): MakeHuman bodies, registrations, model
// outputs. Named by the survey's own CSV columns, in mm (weightkg in kg; the CSV stores tenths).
// Definitions and the landmarks each uses: docs/measurements.md; landmarks: core/landmarks.h
// ansur_landmarks().
//
// Every value is a smooth (or at least continuous) function of the vertices so that a
// least-squares fit can take finite differences: landmark points are fixed template vertices
// (or means of them) and skeleton joints (fixed vertex combinations when the skeleton comes from
// MakeHuman::skeleton_from_body); girths are convex-hull perimeters (a tape bridges hollows) of
// plane sections through landmark-defined planes, never searches for the largest or smallest
// level. Torso girths cut only the torso's triangles (no arm), so a plane level with the armpits
// measures the torso as a tape under the arms does. Where ANSUR searches (maximum protrusion of the buttocks, of the calf) the level is the
// template vertex where it lies on the default body: an APPROXIMATION.
//
// Speed: the constructor sections a reference body once per girth and keeps a tube of triangles
// around each loop; a call only looks at those (falling back to every triangle when the loop
// leaves its tube, which gives the same value, only slower). Span and sleeve outseam pose only
// the handful of landmark vertices they need by linear blend skinning.
#pragma once

#include <Eigen/Core>
#include <array>
#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "core/skeleton.h"

namespace bodymodel {

class AnsurMeasurer {
 public:
  // F: the template's triangles (26 756 by 3, e.g. MakeHuman::body_faces()); W: its skinning
  // weights (13 380 by #bones, MakeHuman::body_weights()); reference_V / reference_skeleton: a
  // body whose sections set the triangle tubes (MakeHuman's default body). InputError when the
  // sizes are not the template's or the skeleton lacks a bone the measurements use.
  AnsurMeasurer(const Eigen::MatrixX3i& F, const SkinWeights& W, const Eigen::MatrixX3d& reference_V,
                const Skeleton& reference_skeleton);

  // The ANSUR columns measured, in the order measure() returns them.
  static const std::vector<std::string>& names();
  // One-line definitions and units ("mm" or "kg") in the same order.
  static const std::vector<std::string>& definitions();
  static const std::vector<std::string>& units();

  // All measurements of a body V (13 380 by 3, mm) whose skeleton (same bones as the reference,
  // e.g. MakeHuman::skeleton_from_body(V)) is `skeleton`. Thread-safe. InputError when V is not
  // 13 380 by 3 or not finite.
  Eigen::VectorXd measure(const Eigen::MatrixX3d& V, const Skeleton& skeleton) const;

  // How many sections since construction left their tube and were cut on the whole mesh (for
  // tests and benchmarks; copies of a measurer share the count).
  long fallback_count() const { return *fallbacks_; }

  // The pose that puts both arms straight and horizontal to the sides (elbows, wrists and
  // fingers extended in line), the survey's position for span, for a body V and its skeleton.
  Pose outstretched_arms_pose(const Eigen::MatrixX3d& V, const Skeleton& skeleton) const;

 private:
  // One girth: which plane (ansur_measure.cc), and the triangles near its loop on the reference.
  struct Section {
    int plane = 0;
    int mode = 0;                  // which loops the girth takes (ansur_measure.cc SectionMode)
    std::vector<int> faces;        // the tube
    std::vector<int> vertices;     // their vertices
    std::vector<char> in_tube;     // per triangle
  };

  Eigen::MatrixX3i F_;
  std::vector<std::array<int, 3>> face_edges_;  // edge ids of each triangle's edges k→k+1
  std::vector<std::array<int, 2>> edge_faces_;  // the (up to two) triangles of each edge
  std::vector<std::array<int, 2>> edge_vertices_;
  std::vector<Section> sections_;
  // Sparse skinning rows of the landmark vertices the posed measurements use.
  std::vector<int> posed_vertices_;
  std::vector<std::vector<std::pair<int, double>>> posed_weights_;
  std::vector<std::string> bone_names_;
  std::vector<char> torso_, everywhere_;        // per triangle: in the torso (no arm), all
  std::vector<int> torso_faces_, all_faces_;

  struct SectionValues {
    double girth = 0, extent_u = 0, extent_w = 0;  // hull perimeter, extents along u and w
  };
  // One section through `origin` square to `normal`, in-plane axes u, w; `anchor` picks the loop.
  SectionValues cut(const Section& s, const Eigen::MatrixX3d& V, const Eigen::Vector3d& origin,
                    const Eigen::Vector3d& normal, const Eigen::Vector3d& u, const Eigen::Vector3d& w,
                    const Eigen::Vector3d& anchor, std::vector<double>& d) const;
  std::shared_ptr<std::atomic<long>> fallbacks_ = std::make_shared<std::atomic<long>>(0);

  void build_tubes(const Eigen::MatrixX3d& V, const Skeleton& skeleton);
};

}  // namespace bodymodel
