// What each fuzz target feeds its input to, shared with the regression test
// (tests/reliability/reader_regressions_test.cc) that replays kept inputs through the same
// calls. A reader may reject input only with InputError or NumericalError; anything else (another
// exception, a crash, a hang, a sanitizer report, std::abort from a failed post-condition here)
// is a bug.
#pragma once

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <string>

#include <unistd.h>

#include "assets/binding.h"
#include "core/error.h"
#include "core/io/bvh.h"
#include "core/io/csv.h"
#include "core/io/file_names.h"
#include "core/io/libigl_formats.h"
#include "core/io/mesh_io.h"
#include "core/io/npz.h"
#include "core/io/pose_csv.h"
#include "core/landmarks.h"
#include "core/makehuman.h"
#include "encoding/encoding_file.h"
#include "encoding/relative_rotation_encoding.h"
#include "markers/c3d.h"
#include "markers/trc.h"
#include "model/database.h"
#include "model/model_file.h"
#include "registration/landmarks.h"
#include "skinning/rig_io.h"

namespace bodymodel::fuzz {

// For readers that only take a path: the input written to one per-process file in /dev/shm
// (memory-backed; the system temp folder when there is none), overwritten on every run.
inline std::filesystem::path input_file(const std::string& bytes, const std::string& ext) {
  static const std::filesystem::path dir = std::filesystem::is_directory("/dev/shm")
                                               ? std::filesystem::path("/dev/shm")
                                               : std::filesystem::temp_directory_path();
  const std::filesystem::path p = dir / ("bodymodel_fuzz_" + std::to_string(::getpid()) + ext);
  std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes;
  return p;
}

// Runs f, swallowing the rejections a reader is allowed (to go on with the next reader).
template <typename F>
void allowing_rejection(F&& f) {
  try {
    f();
  } catch (const InputError&) {
  } catch (const NumericalError&) {
  }
}

inline void check(bool ok) {
  if (!ok) std::abort();  // a post-condition of a successful read failed
}

// Names read from a file that may become file names: each sanitised name must be a plain file
// name (one component that stays in its folder), whatever the file held.
inline void check_names_sanitise(const std::vector<std::string>& names) {
  for (const auto& n : names) check(file_name_problem(sanitized_file_name(n, "x")).empty());
  for (const auto& n : unique_file_names(names, "x")) check(file_name_problem(n).empty());
}

inline void read_obj(const std::string& in) { parse_mesh(in, "obj", "fuzz.obj"); }

inline void read_ply(const std::string& in) {
  allowing_rejection([&] { parse_mesh(in, "ply", "fuzz.ply"); });
  parse_ply_point_cloud(in, "fuzz.ply");
}

// OFF as a mesh (polygons triangulated) and as a point cloud's vertices; what is read must be
// finite with every index in range.
inline void read_off(const std::string& in) {
  const Mesh m = parse_mesh(in, "off", "fuzz.off");
  check(m.V.allFinite() && m.F.rows() > 0 && m.F.minCoeff() >= 0 && m.F.maxCoeff() < m.V.rows());
}

inline void read_npz(const std::string& in) {
  Npz z = Npz::parse(in, "fuzz.npz");
  for (auto& k : z.keys()) {
    allowing_rejection([&] { z.matrix(k); });
    allowing_rejection([&] { z.text(k); });
  }
}

inline void read_bvh(const std::string& in) {
  BvhMotion m = parse_bvh(in, "fuzz.bvh");
  m.rest_positions();
  for (int f = 0; f < std::min(m.frame_count(), 3); ++f)
    for (int j = 0; j < static_cast<int>(m.joints.size()); ++j) bvh_joint_rotation(m, f, j);
}

// MakeHuman .target with a 100-vertex base mesh (so out-of-range indices are reachable).
inline void read_mh_target(const std::string& in) { parse_makehuman_target(in, "fuzz.target", 100); }

inline void read_mhskel(const std::string& in) { parse_makehuman_skeleton(in, "fuzz.mhskel"); }

// .mhw for a three-bone skeleton; the weights must come out normalised and finite.
inline void read_mhw(const std::string& in) {
  const SkinWeights W = parse_makehuman_weights(in, "fuzz.mhw", {"root", "spine", "head"});
  for (int v = 0; v < W.rows(); ++v) {
    double sum = 0;
    for (SkinWeights::InnerIterator it(W, v); it; ++it) {
      check(std::isfinite(it.value()) && it.value() >= 0);
      sum += it.value();
    }
    check(std::abs(sum - 1) < 1e-9);
  }
}

inline void read_landmarks_json(const std::string& in) {
  const auto l = read_landmarks(input_file(in, ".json"), body_landmarks());
  check_landmarks(l, 13380, "fuzz landmarks");
}

// The database's label tables: subjects.csv (labels) and scans.csv; the one CSV dialect
// (core/io/csv.h) writes back what it reads: the same cells after a round trip.
inline void read_labels_csv(const std::string& in) {
  const auto path = input_file(in, ".csv");
  allowing_rejection([&] {
    for (const CsvRecord& r : parse_csv(in, "fuzz.csv")) {
      const auto again = parse_csv(csv_row(r.fields) + "\n", "again.csv");
      const bool blank = r.fields.size() == 1 && r.fields[0].empty();
      check(blank ? again.empty() : again.size() == 1 && again[0].fields == r.fields);
    }
  });
  allowing_rejection([&] { read_subject_table(path); });
  read_scan_table(path);
}

// Pose label files for a three-bone skeleton; what is read must be finite.
inline void read_pose_labels(const std::string& in) {
  static const Skeleton skeleton = [] {
    Skeleton s;
    s.names = {"root", "spine", "head"};
    s.parents = {-1, 0, 1};
    s.heads.resize(3, 3);
    s.heads << 0, 0, 0, 0, 100, 0, 0, 200, 0;
    s.tails.resize(3, 3);
    s.tails << 0, 100, 0, 0, 200, 0, 0, 300, 0;
    return s;
  }();
  const PoseRecord r = read_pose_csv(input_file(in, ".pose.csv"), skeleton.names);
  for (const auto& R : r.pose.rotations) check(R.allFinite());
  check(r.global_rotation.allFinite() && r.global_translation.allFinite() &&
        r.pose.root_translation.allFinite() && std::isfinite(r.scale));
}

inline void read_tgf_file(const std::string& in) { read_tgf(input_file(in, ".tgf")); }

// The same bytes as .dmat (ASCII or binary), .Tmat and a transform animation.
inline void read_dmat_file(const std::string& in) {
  const auto path = input_file(in, ".dmat");
  allowing_rejection([&] { read_dmat(path); });
  allowing_rejection([&] { read_tmat(path); });
  read_transform_animation(path);
}

// A model that loads must also place its skeleton in its template and pose it (small models).
inline void read_model_npz(const std::string& in) {
  const BodyModel model = model_from_npz(Npz::parse(in, "fuzz.npz"), "fuzz.npz");
  check_names_sanitise(model.rig.bone_names);
  check_names_sanitise(model.shape.sample_ids);
  for (const auto& l : model.shape.regression.labels) check_names_sanitise({l.name, l.unit});
  if (!model.rig.empty() && model.rig.bone_count() <= 64 && model.tmpl->rest_vertices().rows() <= 4096) {
    const Eigen::MatrixX3d& V = model.tmpl->rest_vertices();
    Skeleton s;  // what ModelRig::skeleton_for makes (model_rig.cc is not in the fuzz build)
    s.names = model.rig.bone_names;
    s.parents = model.rig.parents;
    s.heads = model.rig.head_regressor * V;
    s.tails = model.rig.tail_regressor * V;
    s.validate();
    check(forward_kinematics(s, Pose::rest(s.bone_count())).size() == static_cast<size_t>(s.bone_count()));
  }
}

// A rig that loads must also evaluate, and its skeleton pose (small rigs: the fuzzer's time is
// better spent parsing).
inline void read_rig_npz(const std::string& in) {
  Eigen::MatrixX3i faces;
  std::vector<BoneTransforms> poses;
  Skeleton skeleton;
  const SkinningRig rig = load_rig(input_file(in, ".npz"), &faces, &poses, &skeleton);
  check_names_sanitise(skeleton.names);
  if (rig.bone_count <= 64 && rig.vertex_count() <= 4096) {
    const BoneTransforms M(static_cast<size_t>(rig.bone_count), Eigen::Affine3d::Identity());
    check(evaluate_rig(rig, M).allFinite());
    for (const auto& P : poses) evaluate_rig(rig, P);
    if (skeleton.bone_count() > 0) forward_kinematics(skeleton, Pose::rest(skeleton.bone_count()));
  }
}

// An encoding file as `decode` reads it: every array checked, the names made into plain,
// distinct file names (they name the decoded meshes), and a small template built.
inline void read_encoding_npz(const std::string& in) {
  const EncodingFile e = parse_encoding_npz(Npz::parse(in, "fuzz.npz"), "fuzz.npz");
  check(e.file_names.size() == static_cast<size_t>(e.encodings.rows()));
  for (size_t i = 0; i < e.file_names.size(); ++i) {
    check(file_name_problem(e.file_names[i]).empty());
    for (size_t k = 0; k < i; ++k) check(e.file_names[i] != e.file_names[k]);
  }
  if (e.template_faces.rows() <= 4096)
    allowing_rejection([&] { EncodingTemplate t(e.template_vertices, e.template_faces); });
}

// MakeHuman asset bindings (.mhclo / .proxy) against a 100-vertex body: every index read must be
// in range, every number finite, the deleted vertices sorted and unique.
inline void read_mhclo(const std::string& in) {
  const AssetBinding b = parse_asset_binding(in, "fuzz.mhclo", 100);
  check(b.vertex_count() > 0 && b.max_vertex_index() < 100 && b.vertices.minCoeff() >= 0);
  check(b.weights.allFinite() && b.offsets.allFinite());
  if (b.scales)
    for (const AssetScale& sc : *b.scales) check(sc.denominator > 0 && std::isfinite(sc.denominator));
  for (size_t k = 0; k < b.deleted_vertices.size(); ++k)
    check(b.deleted_vertices[k] >= 0 && b.deleted_vertices[k] < 100 &&
          (k == 0 || b.deleted_vertices[k - 1] < b.deleted_vertices[k]));
}

// MakeHuman materials (.mhmat): colours finite and non-negative, the [0, 1] numbers in range.
inline void read_mhmat(const std::string& in) {
  const AssetMaterial m = parse_asset_material(in, "fuzz.mhmat");
  for (const auto& c : {m.diffuse_color, m.ambient_color, m.specular_color, m.emissive_color})
    check(c.allFinite() && c.minCoeff() >= 0);
  for (double v : {m.shininess, m.opacity, m.translucency}) check(v >= 0 && v <= 1);
}

// A marker capture that reads must be consistent (labels, 3 columns each, samples finite or
// missing as a whole) and must write back: C3D to C3D bytes that read the same, TRC to TRC text.
inline void check_capture(const MarkerData& d) {
  check_marker_data(d, "fuzz");
  check(d.xyz.cols() == 3 * static_cast<Eigen::Index>(d.labels.size()));
}

inline void read_c3d_bytes(const std::string& in) {
  const MarkerData d = parse_c3d(in, "fuzz.c3d");
  check_capture(d);
  if (d.frame_count() <= 64 && d.first_frame >= 1) {
    allowing_rejection([&] {  // labels a C3D cannot hold (over 255 characters) are refused
      const MarkerData again = parse_c3d(c3d_bytes(d), "again.c3d");
      check(again.labels == d.labels && again.frame_count() == d.frame_count());
    });
  }
}

inline void read_trc_text(const std::string& in) {
  const MarkerData d = parse_trc(in, "fuzz.trc");
  check_capture(d);
  if (d.frame_count() <= 64) {
    const MarkerData again = parse_trc(trc_text(d), "again.trc");
    check(again.labels == d.labels && again.frame_count() == d.frame_count());
  }
}

// fuzz target name (without "fuzz_") → reader.
inline const std::map<std::string, std::function<void(const std::string&)>>& readers() {
  static const std::map<std::string, std::function<void(const std::string&)>> table = {
      {"obj", read_obj},           {"ply", read_ply},           {"off", read_off},
      {"npz", read_npz},           {"bvh", read_bvh},
      {"mh_target", read_mh_target}, {"mhskel", read_mhskel},
      {"mhw", read_mhw},           {"landmarks", read_landmarks_json},
      {"labels_csv", read_labels_csv}, {"pose_csv", read_pose_labels},
      {"tgf", read_tgf_file},      {"dmat", read_dmat_file},
      {"model_npz", read_model_npz}, {"rig_npz", read_rig_npz},
      {"encoding_npz", read_encoding_npz},
      {"mhclo", read_mhclo},       {"mhmat", read_mhmat},
      {"c3d", read_c3d_bytes},     {"trc", read_trc_text}};
  return table;
}

}  // namespace bodymodel::fuzz
