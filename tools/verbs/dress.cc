// bodymodel dress --outfit NAME[,NAME...] [--gender ..] [--pose NAME|file.bvh [--frame k]] --out dressed.obj|ply|glb
//
// A MakeHuman body wearing MakeHuman assets (docs/assets.md): each asset fitted by its binding,
// skinned with the weights carried through it, garments pushed out of the skin; written as one
// mesh with a colour per part (OBJ + MTL, a PLY with vertex colours, or a skinned glb with a
// material per part).
#include <fmt/format.h>

#include <filesystem>
#include <sstream>

#include "assets/dress.h"
#include "core/data_path.h"
#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/bvh.h"
#include "core/io/mesh_io.h"
#include "core/makehuman.h"
#include "skinning/gltf_export.h"
#include "tools/verb.h"
#include "tools/verbs/slider_options.h"

namespace bodymodel {
namespace {

struct DressArgs {
  MacroSettings settings;
  std::vector<std::string> outfit;
  std::string pose;
  int frame = 0;
  bool no_fix = false;
  std::string out;
};

// OBJ with one object and material per part, and its MTL beside it (written first, so the OBJ
// never names a missing file).
void write_obj_with_materials(const std::filesystem::path& out, const std::vector<DressedPart>& parts) {
  std::filesystem::path mtl = out;
  mtl.replace_extension(".mtl");
  std::string m;
  for (const DressedPart& p : parts)
    m += fmt::format("newmtl {}\nKd {:.4f} {:.4f} {:.4f}\n\n", p.name, p.colour[0], p.colour[1], p.colour[2]);
  write_text_file(mtl, m);
  std::string o = fmt::format("# bodymodel dress, millimetres\nmtllib {}\n", mtl.filename().string());
  int base = 1;
  for (const DressedPart& p : parts) {
    o += fmt::format("o {}\nusemtl {}\n", p.name, p.name);
    for (Eigen::Index v = 0; v < p.V.rows(); ++v) o += fmt::format("v {:.3f} {:.3f} {:.3f}\n", p.V(v, 0), p.V(v, 1), p.V(v, 2));
    for (Eigen::Index f = 0; f < p.F.rows(); ++f)
      o += fmt::format("f {} {} {}\n", base + p.F(f, 0), base + p.F(f, 1), base + p.F(f, 2));
    base += static_cast<int>(p.V.rows());
  }
  write_text_file(out, o);
}

void write_ply_with_colours(const std::filesystem::path& out, const std::vector<DressedPart>& parts) {
  Eigen::Index nv = 0, nf = 0;
  for (const DressedPart& p : parts) nv += p.V.rows(), nf += p.F.rows();
  Eigen::MatrixX3d V(nv, 3), C(nv, 3);
  Eigen::MatrixX3i F(nf, 3);
  Eigen::Index v0 = 0, f0 = 0;
  for (const DressedPart& p : parts) {
    V.middleRows(v0, p.V.rows()) = p.V;
    C.middleRows(v0, p.V.rows()).rowwise() = p.colour.transpose();
    F.middleRows(f0, p.F.rows()) = p.F.array() + static_cast<int>(v0);
    v0 += p.V.rows(), f0 += p.F.rows();
  }
  write_mesh(out, V, F, C);
}

// One skinned glTF mesh, a primitive and material per part, the pose (if any) as a one-frame clip.
void write_glb(const std::filesystem::path& out, const std::vector<DressedPart>& parts, const Skeleton& skeleton,
               const BoneTransforms* pose) {
  Eigen::Index nv = 0, nf = 0;
  for (const DressedPart& p : parts) nv += p.V.rows(), nf += p.F.rows();
  Eigen::MatrixX3d V(nv, 3);
  Eigen::MatrixX3i F(nf, 3);
  std::vector<Eigen::Triplet<double>> t;
  GltfExportOptions o;
  o.mesh_name = "dressed";
  Eigen::Index v0 = 0, f0 = 0;
  for (const DressedPart& p : parts) {
    V.middleRows(v0, p.V.rows()) = p.V;
    F.middleRows(f0, p.F.rows()) = p.F.array() + static_cast<int>(v0);
    for (int r = 0; r < p.weights.outerSize(); ++r)
      for (SkinWeights::InnerIterator it(p.weights, r); it; ++it) t.emplace_back(v0 + r, it.col(), it.value());
    o.parts.push_back({p.name, static_cast<int>(f0), static_cast<int>(p.F.rows()), p.colour.cwiseMin(1.0), p.roughness});
    v0 += p.V.rows(), f0 += p.F.rows();
  }
  SkinWeights W(nv, skeleton.bone_count());
  W.setFromTriplets(t.begin(), t.end());
  GltfAnimation clip;
  clip.name = "pose";
  if (pose) clip.frames.push_back(*pose);
  write_skinned_gltf(out, V, F, {}, skeleton, W, pose ? &clip : nullptr, o);
}

void run(const DressArgs& a) {
  const std::string ext = std::filesystem::path(a.out).extension().string();
  if (ext != ".obj" && ext != ".ply" && ext != ".glb")
    throw InputError("--out '" + a.out + "': expected an .obj, .ply or .glb file name");
  a.settings.validate();
  const std::filesystem::path mh_dir = data_file("makehuman");
  std::vector<Asset> outfit;
  for (const std::string& name : a.outfit) outfit.push_back(load_asset(find_asset(mh_dir / "assets", name)));
  const MakeHuman mh = MakeHuman::load(mh_dir);
  const Eigen::MatrixX3d rest = mh.build_vertices(a.settings);
  const Skeleton skeleton = mh.skeleton(rest);
  BoneTransforms M;
  if (!a.pose.empty()) {
    const std::filesystem::path file = a.pose.find('/') != std::string::npos || std::filesystem::path(a.pose).extension() == ".bvh"
                                           ? std::filesystem::path(a.pose) : mh.pose_file(a.pose);
    const BvhMotion clip = read_bvh(file);
    if (a.frame < 0 || a.frame >= clip.frame_count())
      throw InputError(fmt::format("--frame {}: '{}' has frames 0..{}", a.frame, file.string(), clip.frame_count() - 1));
    M = forward_kinematics(skeleton, bvh_frame_to_pose(clip, a.frame, skeleton));
  }
  DressOptions options;
  options.fix_penetration = !a.no_fix;
  // A glb holds the rest pose (skinned; the pose is its one-frame clip), so it is dressed at rest.
  const bool posed = !a.pose.empty() && ext != ".glb";
  const std::vector<DressedPart> parts = dress_body(rest, mh.body_faces(), mh.weights(), posed ? &M : nullptr,
                                                    outfit, options);
  fmt::print("{:<22} {:<10} {:>8} {:>8} {:>12} {:>12}\n", "part", "kind", "vertices", "faces", "inside>2mm%",
             "after fix%");
  for (const DressedPart& p : parts) {
    fmt::print("{:<22} {:<10} {:>8} {:>8}", p.name, p.kind, p.V.rows(), p.F.rows());
    if (p.garment) fmt::print(" {:>12.2f} {:>12.2f}", 100 * p.before.fraction, 100 * p.after.fraction);
    fmt::print("\n");
  }
  if (ext == ".obj") write_obj_with_materials(a.out, parts);
  else if (ext == ".ply") write_ply_with_colours(a.out, parts);
  else write_glb(a.out, parts, skeleton, a.pose.empty() ? nullptr : &M);
  fmt::print("wrote:    {} ({})\n", a.out,
             ext == ".obj" ? "mm, materials in the .mtl beside it"
                           : ext == ".ply" ? "mm, vertex colours" : "metres, skinned, a material per part");
}

}  // namespace

BODYMODEL_VERB(add_dress_verb) {
  auto a = std::make_shared<DressArgs>();
  auto* cmd = app.add_subcommand(
      "dress",
      "Dress a MakeHuman body in MakeHuman assets (clothes, shoes, hair, eyebrows, eyelashes, eyes,\n"
      "teeth): fitted by their bindings, posed with the body, garments pushed out of the skin.");
  cli::add_macro_slider_options(cmd, a->settings);
  cmd->add_option("--outfit", a->outfit, "asset names, comma-separated (e.g. male_casualsuit01,shoes01,short02)")
      ->delimiter(',')->required();
  cmd->add_option("--pose", a->pose, "a static pose name (motion/poses: fight01, sit01, ...) or a BVH file for the "
                  "default skeleton");
  cmd->add_option("--frame", a->frame, "frame of the BVH to use")->capture_default_str();
  cmd->add_flag("--no-fix", a->no_fix, "do not push garments out of the skin (only measure)");
  cmd->add_option("--out", a->out, "output: .obj (+ .mtl, a material per part), .ply (vertex colours) or .glb "
                  "(skinned, rest pose, the --pose as a one-frame clip)")
      ->required();
  cmd->callback([a] { run(*a); });
}

}  // namespace bodymodel
