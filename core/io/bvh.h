// BVH motion files: reader, writer, Euler-angle helpers, and posing a Skeleton by bone name.
//
// A BVH file is a joint hierarchy (OFFSET, CHANNELS per joint, End Sites) and a MOTION block
// with one line of channel values per frame. Rotation channels are Euler angles in DEGREES,
// composed in the order listed (`Zrotation Xrotation Yrotation` → R = Rz(z)·Rx(x)·Ry(y)),
// each joint's rotation relative to its parent in world-aligned axes. The reader is strict: any malformed input throws InputError naming the file and line.
//
// Posing (data README §7.1, MakeHuman's own rule): the up axis is guessed from the rest offset
// of lowerleg02.L's child (|z| > |y| → Z-up, converted to the hm08 Y-up frame as
// (x, y, z) → (x, z, −y)); each joint's rotation is conjugated into hm08 axes and given to the
// skeleton bone of the same name (missing bones: identity); BVH OFFSETs are ignored except for
// the up-axis guess and the translation scale. See core/retarget.h for clips whose skeleton
// has other bone names (the CMU clips).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/skeleton.h"

namespace bodymodel {

enum class BvhChannel { kXposition, kYposition, kZposition, kXrotation, kYrotation, kZrotation };

// "Xposition", ..., "Zrotation".
std::string_view bvh_channel_name(BvhChannel c);
// 0, 1, 2 for the X, Y, Z channels of either kind.
inline int bvh_channel_axis(BvhChannel c) { return static_cast<int>(c) % 3; }
inline bool bvh_is_rotation(BvhChannel c) { return static_cast<int>(c) >= 3; }

struct BvhJoint {
  std::string name;
  int parent = -1;                               // index into BvhMotion::joints, −1 for a root
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // rest offset from the parent, file units
  std::vector<BvhChannel> channels;              // in file order
  int first_channel = 0;                         // column of channels[0] in a frame row
  std::optional<Eigen::Vector3d> end_site;       // End Site offset, if the joint has one
};

struct BvhMotion {
  std::vector<BvhJoint> joints;  // file (depth-first) order: parents before children
  double frame_time = 1.0 / 30;  // seconds per frame
  Eigen::MatrixXd frames;        // #frames by #channels; positions in file units, angles in degrees
  std::string source;            // the file it was read from (parse_bvh's `source`), for messages

  int frame_count() const { return static_cast<int>(frames.rows()); }
  int channel_count() const;
  // Index of the joint called `name`, or −1.
  int find(std::string_view name) const;
  // Rest positions of every joint (accumulated OFFSETs, file units, file axes): #J by 3.
  Eigen::MatrixX3d rest_positions() const;
  // Throws InputError if the structure is inconsistent (channel columns, parents, frame width).
  void validate() const;
};

// Parses BVH text; `source` names the file in error messages.
BvhMotion parse_bvh(std::string_view text, const std::string& source);
BvhMotion read_bvh(const std::filesystem::path& path);
// Writes BVH text (tabs, 6 decimals) atomically.
std::string format_bvh(const BvhMotion& motion);
void write_bvh(const std::filesystem::path& path, const BvhMotion& motion);

// ---- Euler angles ------------------------------------------------------------------------

// Rotation R = R_{axes[0]}(deg[0]) · R_{axes[1]}(deg[1]) · R_{axes[2]}(deg[2]); axes are 0..2
// (X, Y, Z) and must be distinct; angles in degrees (the BVH representation).
Eigen::Matrix3d euler_to_rotation(const std::array<int, 3>& axes, const Eigen::Vector3d& degrees);
// Inverse of euler_to_rotation: angles in degrees with the middle one in [−90, 90] and the
// others in (−180, 180]. At gimbal lock (middle ±90) the first angle is set to 0.
Eigen::Vector3d rotation_to_euler(const Eigen::Matrix3d& R, const std::array<int, 3>& axes);

// Rotation axes of a joint's rotation channels in file order (e.g. {2, 0, 1} for Z X Y);
// joints with fewer than three rotation channels get the missing axes appended.
std::array<int, 3> bvh_rotation_order(const BvhJoint& joint);
// Rotation of `joint` in `frame` in the file's axes (identity for a joint without rotation
// channels).
Eigen::Matrix3d bvh_joint_rotation(const BvhMotion& motion, int frame, int joint);
// Root position channels of `frame` (file units and axes); the root OFFSET when it has none.
Eigen::Vector3d bvh_root_position(const BvhMotion& motion, int frame);
// Stores R in the rotation channels of `joint` in `frame` (needs three rotation channels).
void set_bvh_joint_rotation(BvhMotion& motion, int frame, int joint, const Eigen::Matrix3d& R);

// ---- applying a frame to a skeleton --------------------------------------------------------

enum class BvhUpAxis { kY, kZ };

// MakeHuman's heuristic (README §7.1): the OFFSET of lowerleg02.L's first child; |z| > |y|
// means Z-up. Files without that joint are taken as Y-up.
BvhUpAxis guess_bvh_up_axis(const BvhMotion& motion);
// Matrix C taking file axes to hm08 axes (Y-up, faces +Z): identity for Y-up, (x,y,z) →
// (x, z, −y) for Z-up. A file rotation R becomes C R Cᵀ.
Eigen::Matrix3d bvh_axis_conversion(BvhUpAxis up);

struct BvhPoseOptions {
  std::optional<BvhUpAxis> up_axis;   // default: guess_bvh_up_axis
  // Apply the root's position channels (README §7.1 step 3). Off by default: the reference
  // poses and most fitting use rotations only.
  bool apply_root_translation = false;
  // Scale from file units to skeleton units for the root translation; default: the
  // skeleton's upperleg02.L length / the file's upperleg02.L→child OFFSET length.
  std::optional<double> translation_scale;
};

// Pose of `skeleton` for `frame`: every skeleton bone with a BVH joint of the same name gets
// that joint's rotation (in hm08 axes); other bones keep identity; BVH joints the skeleton
// lacks are ignored. With translation, root_translation = scale · C · (root position channels):
// MakeHuman's files store the root's displacement from the rest root there (README §7.1;
// with this rule the standing poses land on the rest floor).
Pose bvh_frame_to_pose(const BvhMotion& motion, int frame, const Skeleton& skeleton,
                       const BvhPoseOptions& options = {});

// The opposite direction: a BVH motion with one frame per pose for `skeleton` (Y-up, hm08
// axes, skeleton units; OFFSETs = rest head − parent rest head, End Sites at leaf tails;
// channels `Xrotation Yrotation Zrotation`, plus `X/Y/Zposition` first on the root, which hold
// root_translation).
BvhMotion skeleton_poses_to_bvh(const Skeleton& skeleton, const std::vector<Pose>& poses,
                                double frame_time = 1.0 / 30);

}  // namespace bodymodel
