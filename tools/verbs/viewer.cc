// `bodymodel viewer`: a static, offline 3D viewer folder (index.html + three.js + the data as a
// script, so it opens from the file system with no server and no network): orbit meshes, play a
// clip on rigs skinned by our own WebGL vertex shader (LBS, Animation Space, MWE), compare
// methods and show the per-vertex distance to a reference rig. check.json holds the C++
// evaluator's positions on a few frames, for the browser test (tests/viewer/).
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/bvh.h"
#include "core/io/json_text.h"
#include "core/io/mesh_io.h"
#include "core/retarget.h"
#include "markers/marker_data.h"
#include "skinning/rig_io.h"
#include "tools/console.h"
#include "tools/pipeline/character.h"
#include "tools/pipeline/character_file.h"
#include "tools/pipeline/marker_pictures.h"
#include "tools/pipeline/output_folder.h"
#include "tools/verb.h"
#include "tools/verbs/skin_motion.h"
#include "tools/viewer/viewer_assets.h"

namespace bodymodel::cli {
namespace fs = std::filesystem;
namespace {

struct ViewerArgs {
  std::vector<std::string> rigs, meshes;
  // (mesh, reference): the mesh coloured by its per-vertex distance to the reference (same
  // vertices in the same order), e.g. a registration against the true body.
  std::vector<std::pair<std::string, std::string>> error_meshes;
  std::vector<std::string> error_mesh_args;  // as given: MESH REFERENCE MESH REFERENCE ...
  double error_scale = 30;  // mm at the red end of the colour map
  std::string bvh, out, three;
  std::string markers, marker_report;  // a capture (.c3d/.trc) and the markers clean report of its gaps
  int frames = 48, every = 2, first = 0;
  std::vector<int> check_frames = {0, 1, 2};
  bool force = false, no_check = false;
};

template <class T>
std::string b64(const std::vector<T>& v) { return base64(v.data(), v.size() * sizeof(T)); }

// One rig as the shader reads it: 4 RGBA float texels per (vertex, slot):
// (bone, c0, c1, c2) (c3..c6) (c7..c10) (c11, 0, 0, 0); bone −1 = unused slot.
std::vector<float> rig_texels(const SkinningRig& r) {
  const int K = r.max_influences(), c = coefficients_per_influence(r.method);
  std::vector<float> t(static_cast<size_t>(r.vertex_count()) * K * 16, 0.f);
  for (int v = 0; v < r.vertex_count(); ++v)
    for (int k = 0; k < K; ++k) {
      float* q = &t[(static_cast<size_t>(v) * K + k) * 16];
      q[0] = static_cast<float>(r.influences(v, k));
      // Coefficient j sits at float 1 + j of the 16 (texel boundaries fall where the shader expects).
      for (int j = 0; j < c; ++j) q[1 + j] = static_cast<float>(r.coefficients(v, k * c + j));
    }
  return t;
}

struct NamedRig {
  std::string name;
  SkinningRig rig;
};


struct LoadedRigs {
  std::vector<NamedRig> rigs;
  Eigen::MatrixX3i F;
  Skeleton skeleton;
  std::vector<char> driven;
};

// The --rig files: a character's rig (its method and its SSD base) or a plain rig; all alike.
LoadedRigs load_viewer_rigs(const ViewerArgs& a) {
  LoadedRigs L;
  std::vector<NamedRig>& rigs = L.rigs;
  Eigen::MatrixX3i& F = L.F;
  Skeleton& skeleton = L.skeleton;
  std::vector<char>& driven = L.driven;
  for (const auto& path : a.rigs) {
    bool character = false;
    try {
      CharacterRigFile c = load_character_rig(path);
      character = true;
      if (skeleton.bone_count() == 0) {
        skeleton = c.skeleton;
        driven = c.driven;
      }
      if (F.rows() == 0) F = c.F;
      rigs.push_back({skinning_method_name(c.rig.method), c.rig});
      rigs.push_back({"ssd (base)", c.lbs});
    } catch (const InputError&) {
      if (character) throw;
    }
    if (character) continue;
    Eigen::MatrixX3i f;
    Skeleton stored;
    SkinningRig r = load_rig(path, &f, nullptr, &stored);
    if (F.rows() == 0) F = f;
    if (skeleton.bone_count() == 0) {
      std::string source;
      skeleton = skeleton_for_rig(r, stored, &source);
    }
    rigs.push_back({skinning_method_name(r.method), r});
  }
  for (auto& r : rigs) {
    if (r.rig.method == SkinningMethod::dqs) throw InputError("the viewer's shader has no dqs path (give ssd, as or mwe rigs)");
    if (r.rig.vertex_count() != rigs[0].rig.vertex_count() || r.rig.bone_count != rigs[0].rig.bone_count)
      throw InputError(fmt::format("rig '{}' has {} vertices and {} bones; the first has {} and {}", r.name,
                                   r.rig.vertex_count(), r.rig.bone_count, rigs[0].rig.vertex_count(), rigs[0].rig.bone_count));
  }
  if (!rigs.empty() && F.rows() == 0) throw InputError("'" + a.rigs[0] + "' stores no faces (the viewer draws triangles)");
  if (!rigs.empty() && skeleton.bone_count() != rigs[0].rig.bone_count)
    throw InputError("'" + a.rigs[0] + "' has no skeleton (store one, or use a MakeHuman-body rig)");

  return L;
}

// The clip's bone maps and every rig's texels into d; returns the maps of the frames written.
std::vector<BoneTransforms> add_animation(const ViewerArgs& a, const LoadedRigs& L, nlohmann::json& d,
                                          std::vector<int>& frames) {
  const std::vector<NamedRig>& rigs = L.rigs;
  const Eigen::MatrixX3i& F = L.F;
  const Skeleton& skeleton = L.skeleton;
  const std::vector<char>& driven = L.driven;
  std::vector<BoneTransforms> maps;
  const BvhMotion clip = read_bvh(a.bvh);
  if (clip.frame_count() == 0) throw InputError("'" + a.bvh + "' has no frames");
  if (a.first < 0 || a.first >= clip.frame_count())
    throw InputError(fmt::format("'{}' has {} frames; --first {} is out of range", a.bvh, clip.frame_count(), a.first));
  // In place (no root translation): the camera orbits a body that stays put.
  const std::vector<Pose> poses = poses_from_bvh(clip, skeleton, data_file("makehuman"), false);
  for (int f = a.first; f < clip.frame_count() && static_cast<int>(frames.size()) < a.frames; f += std::max(1, a.every)) {
    frames.push_back(f);
    const Pose& p = poses[static_cast<size_t>(f)];
    maps.push_back(forward_kinematics(skeleton, driven.empty() ? p : restrict_pose(p, driven)));
  }
  const Eigen::MatrixX3d& rest = rigs[0].rig.rest;
  std::vector<float> restf, bones;
  for (int v = 0; v < rest.rows(); ++v)
    for (int k = 0; k < 3; ++k) restf.push_back(static_cast<float>(rest(v, k)));
  // Bone maps: 3 texels per (frame, bone), the rows of [R t].
  for (auto& M : maps)
    for (auto& m : M)
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) bones.push_back(static_cast<float>(m.matrix()(r, c)));
  std::vector<uint32_t> faces;
  for (int i = 0; i < F.rows(); ++i)
    for (int k = 0; k < 3; ++k) faces.push_back(static_cast<uint32_t>(F(i, k)));
  d["rest"] = b64(restf);
  d["faces"] = b64(faces);
  d["vertex_count"] = rest.rows();
  d["bone_count"] = skeleton.bone_count();
  d["frames"] = frames.size();
  d["frame_time"] = clip.frame_time * std::max(1, a.every);
  d["transforms"] = b64(bones);
  d["height"] = rest.col(1).maxCoeff() - rest.col(1).minCoeff();
  d["clip"] = fs::path(a.bvh).filename().string();
  for (auto& r : rigs)
    d["rigs"].push_back({{"name", r.name}, {"method", skinning_method_name(r.rig.method)},
                         {"K", r.rig.max_influences()}, {"texels", b64(rig_texels(r.rig))}});
  return maps;
}

// Static meshes (and error meshes coloured by their distance to a reference) into d.
void add_static_meshes(const ViewerArgs& a, nlohmann::json& d) {
  // Static meshes, named by file (with the folder when two files share a name, as the
  // crowd's char_NNN/body.obj do).
  std::vector<std::string> paths = a.meshes;
  for (auto& [m, r] : a.error_meshes) paths.push_back(m);
  std::map<std::string, int> seen;
  for (auto& p : paths) ++seen[fs::path(p).filename().string()];
  auto name_of = [&](const std::string& p) {
    const fs::path f(p);
    return seen[f.filename().string()] > 1 ? (f.parent_path().filename() / f.filename()).string() : f.filename().string();
  };
  auto add_mesh = [&](const std::string& path, const Mesh& m, nlohmann::json extra) {
    std::vector<float> V;
    std::vector<uint32_t> f;
    for (int v = 0; v < m.V.rows(); ++v)
      for (int k = 0; k < 3; ++k) V.push_back(static_cast<float>(m.V(v, k)));
    for (int i = 0; i < m.F.rows(); ++i)
      for (int k = 0; k < 3; ++k) f.push_back(static_cast<uint32_t>(m.F(i, k)));
    if (f.empty()) throw InputError("'" + path + "' has no faces (the viewer draws triangles)");
    extra["name"] = name_of(path);
    extra["positions"] = b64(V);
    extra["faces"] = b64(f);
    d["meshes"].push_back(extra);
  };
  for (const auto& path : a.meshes) add_mesh(path, read_mesh(path), nlohmann::json::object());
  for (const auto& [path, ref] : a.error_meshes) {
    const Mesh m = read_mesh(path), r = read_mesh(ref);
    if (m.V.rows() != r.V.rows())
      throw InputError(fmt::format("--error-mesh: '{}' has {} vertices, its reference '{}' {} (the error is per vertex)", path,
                                   m.V.rows(), ref, r.V.rows()));
    const Eigen::VectorXd e = (m.V - r.V).rowwise().norm();
    std::vector<float> ef(e.data(), e.data() + e.size());
    add_mesh(path, m, {{"errors", b64(ef)}, {"reference", fs::path(ref).filename().string()},
                       {"error_mean", e.mean()}, {"error_max", e.maxCoeff()}});
  }
}

// The capture as points over time: positions (frames × markers × 3, float32, mm; 0 where missing)
// and a state per sample: 0 seen, 1 filled by the cleaning (inside a gap of the report), 2 missing.
void add_markers(const ViewerArgs& a, nlohmann::json& d) {
  const MarkerData m = read_markers(a.markers);
  const std::vector<std::vector<char>> filled =
      filled_mask(m, a.marker_report.empty() ? std::vector<GapRecord>() : read_clean_gaps(a.marker_report));
  long filled_samples = 0;
  for (const auto& row : filled) filled_samples += std::count(row.begin(), row.end(), 1);
  std::vector<float> pos;
  std::vector<uint8_t> state;
  for (int t = 0; t < m.frame_count(); ++t)
    for (int i = 0; i < m.marker_count(); ++i) {
      const bool seen = m.present(t, i);
      for (int k = 0; k < 3; ++k) pos.push_back(seen ? static_cast<float>(m.xyz(t, 3 * i + k)) : 0.f);
      state.push_back(!seen ? 2 : filled[t][i] ? 1 : 0);
    }
  d["markers"] = {{"name", fs::path(a.markers).filename().string()}, {"count", m.marker_count()},
                  {"frames", m.frame_count()}, {"rate", m.rate}, {"positions", b64(pos)}, {"state", b64(state)},
                  {"filled_samples", filled_samples}, {"missing", missing_fraction(m)}};
}

// check.json: the C++ (double precision) evaluator's positions on the check frames.
nlohmann::json check_json(const ViewerArgs& a, const std::vector<NamedRig>& rigs,
                          const std::vector<BoneTransforms>& maps, const nlohmann::json& d) {
  nlohmann::json check;
  check["height"] = d["height"];
  for (int f : a.check_frames) {
    if (f < 0 || f >= static_cast<int>(maps.size()))
      throw InputError(fmt::format("--check-frames: frame {} is outside the {} frames written", f, maps.size()));
    check["frames"].push_back(f);
  }
  for (auto& r : rigs) {
    nlohmann::json jr = {{"name", r.name}};
    for (int f : a.check_frames) {
      const Eigen::MatrixX3d P = evaluate_rig(r.rig, maps[static_cast<size_t>(f)]);
      std::vector<double> flat(static_cast<size_t>(P.size()));
      for (int v = 0; v < P.rows(); ++v)
        for (int k = 0; k < 3; ++k) flat[static_cast<size_t>(3 * v + k)] = P(v, k);
      jr["positions"].push_back(flat);
    }
    check["rigs"].push_back(jr);
  }
  return check;
}

void run_viewer(const ViewerArgs& a) {
  if (a.rigs.empty() && a.meshes.empty() && a.error_meshes.empty() && a.markers.empty())
    throw InputError("give at least one --rig, --mesh, --error-mesh or --markers");
  if (!a.marker_report.empty() && a.markers.empty()) throw InputError("--marker-report needs --markers");
  if (!(a.error_scale > 0)) throw InputError(fmt::format("--error-scale must be positive, found {}", a.error_scale));
  if (!a.rigs.empty() && a.bvh.empty()) throw InputError("--rig needs --bvh (the clip to play)");
  if (a.frames < 1) throw InputError(fmt::format("--frames must be at least 1, found {}", a.frames));
  const LoadedRigs L = load_viewer_rigs(a);
  const std::vector<NamedRig>& rigs = L.rigs;
  nlohmann::json d;
  std::vector<int> frames;
  std::vector<BoneTransforms> maps;
  if (!rigs.empty()) maps = add_animation(a, L, d, frames);
  add_static_meshes(a, d);
  if (!a.markers.empty()) add_markers(a, d);
  d["error_scale"] = a.error_scale;
  nlohmann::json check;
  if (!rigs.empty() && !a.no_check) check = check_json(a, rigs, maps, d);

  // Checked after the inputs, so a bad input is named first.
  const fs::path three = a.three.empty() ? default_three_js() : fs::path(a.three);
  if (three.empty() || !fs::is_regular_file(three))
    throw InputError("three.js not found at '" + three.string() +
                     "' (scripts/setup.sh installs it into the build folder; or give --three FILE / BODYMODEL_THREE)");
  StagedFolder out(a.out, a.force);
  write_text_file(out / "index.html", viewer_index_html());
  write_text_file(out / "viewer.js", viewer_js());
  write_text_file(out / "viewer_data.js", "window.VIEWER_DATA = " + json_text(d) + ";\n");
  if (!rigs.empty() && !a.no_check) write_text_file(out / "check.json", json_text(check));
  std::error_code ec;
  fs::copy_file(three, out / "three.min.js", ec);
  if (ec) throw InputError("cannot copy '" + three.string() + "': " + ec.message());
  out.commit();
  fmt::print("viewer: {} rig(s), {} frame(s), {} mesh(es){} → {}\n", rigs.size(), frames.size(),
             a.meshes.size() + a.error_meshes.size(),
             a.markers.empty() ? "" : fmt::format(", {} markers × {} frames", d["markers"]["count"].get<int>(),
                                                  d["markers"]["frames"].get<int>()),
             (fs::path(a.out) / "index.html").string());
}

}  // namespace

BODYMODEL_VERB(add_viewer_verb) {
  auto a = std::make_shared<ViewerArgs>();
  auto* cmd = app.add_subcommand(
      "viewer",
      "An offline interactive 3D viewer folder (OUT/index.html opens from the file system): orbit\n"
      "meshes, play a BVH clip on rigs skinned in a WebGL vertex shader (ssd, as, mwe; a character\n"
      "rig brings its MWE rig and its SSD base), switch methods and show the per-vertex distance\n"
      "to a reference rig; meshes coloured by their distance to a reference; a marker capture playing, the samples\n"
      "the cleaning filled in another colour. OUT/check.json: the C++ evaluator's positions on --check-frames.");
  cmd->add_option("--rig", a->rigs, "Skinning rig (.npz from skin fit or character), repeatable");
  cmd->add_option("--mesh", a->meshes, "Static mesh to orbit (OBJ, PLY, OFF), repeatable");
  cmd->add_option("--error-mesh", a->error_mesh_args,
                  "MESH REFERENCE: MESH coloured by its per-vertex distance to REFERENCE (same vertex order,\n"
                  "e.g. a registration and the true body), with a legend; repeatable")
      ->expected(2)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  cmd->add_option("--error-scale", a->error_scale, "Distance (mm) at the red end of the colour map")
      ->capture_default_str();
  cmd->add_option("--markers", a->markers, "Marker capture (.c3d or .trc) drawn as points playing over time");
  cmd->add_option("--marker-report", a->marker_report,
                  "The markers clean report (JSON) of --markers: the samples in its gaps are drawn in the filled colour");
  cmd->add_option("--bvh", a->bvh, "Clip played on the rigs (CMU clips are retargeted)");
  cmd->add_option("--frames", a->frames, "Clip frames stored")->capture_default_str();
  cmd->add_option("--every", a->every, "Keep every n-th clip frame")->capture_default_str();
  cmd->add_option("--first", a->first, "First clip frame")->capture_default_str();
  cmd->add_option("--check-frames", a->check_frames, "Stored frames evaluated in C++ into check.json")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_flag("--no-check", a->no_check, "Write no check.json (it is for tests: ~1.5 MB per rig)");
  cmd->add_option("--three", a->three, "three.min.js to copy (default: the build folder's npm install)");
  cmd->add_option("--out", a->out, "Output folder (must not exist unless --force)")->required();
  cmd->add_flag("--force", a->force, "Replace an existing output folder");
  cmd->callback([a] {
    if (a->error_mesh_args.size() % 2)
      throw InputError(fmt::format("--error-mesh takes two files each time (MESH REFERENCE); {} given",
                                   a->error_mesh_args.size()));
    for (size_t i = 0; i + 1 < a->error_mesh_args.size(); i += 2)
      a->error_meshes.emplace_back(a->error_mesh_args[i], a->error_mesh_args[i + 1]);
    run_viewer(*a);
  });
}

}  // namespace bodymodel::cli
