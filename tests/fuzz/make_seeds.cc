// Writes small seed inputs for every fuzz target into <dir>/<target>/ (made in code: no copies
// of the shared data).
#include <filesystem>
#include <fstream>
#include <iostream>

#include "core/io/bvh.h"
#include "core/io/libigl_formats.h"
#include "core/io/mesh_io.h"
#include "core/io/npz.h"
#include "encoding/encoding_file.h"
#include "markers/c3d.h"
#include "markers/trc.h"
#include "model/model_file.h"
#include "skinning/rig_io.h"
#include "tiny_files.h"

namespace fs = std::filesystem;
using namespace bodymodel;

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: make_seeds DIR\n";
    return 2;
  }
  fs::path dir = argv[1];
  auto put = [&](const std::string& target, const std::string& name, const std::string& bytes) {
    fs::create_directories(dir / target);
    std::ofstream(dir / target / name, std::ios::binary) << bytes;
  };
  Eigen::MatrixX3d V(4, 3);
  V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  Eigen::MatrixX3i F(4, 3);
  F << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  fs::path tmp = fs::temp_directory_path() / "bodymodel_seeds";
  fs::create_directories(tmp);
  write_mesh(tmp / "t.obj", V, F);
  write_mesh(tmp / "t.ply", V, F);
  write_mesh(tmp / "a.ply", V, F, Eigen::MatrixX3d::Constant(4, 3, 0.5), true);
  Eigen::MatrixX3d N = (V.rowwise() + Eigen::RowVector3d(0.1, 0.2, 0.3)).rowwise().normalized();
  PointCloud pc{V, N};
  write_point_cloud(tmp / "p.ply", pc);
  for (auto n : {"t.obj"}) put("fuzz_obj", n, std::string(std::istreambuf_iterator<char>(std::ifstream(tmp / n).rdbuf()), {}));
  put("fuzz_off", "tri.off", "OFF\n# c\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n");
  put("fuzz_obj", "quads.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\ng body\nf 1/1/1 2/2/2 3/3/3 4/4/4\nf -1 -2 -3\n");
  write_mesh(tmp / "t.off", V, F);
  put("fuzz_off", "t.off", std::string(std::istreambuf_iterator<char>(std::ifstream(tmp / "t.off").rdbuf()), {}));
  put("fuzz_off", "variants.off", "COFF 5 2 0\n# c\n0 0 0 1 1 1 1\n1 0 0 1 1 1 1\n1 1 0 1 1 1 1\n"
      "0 1 0 1 1 1 1\n0 0 1 1 1 1 1\n4 0 1 2 3\n3 0 1 4 255 0 0\n");
  for (auto n : {"t.ply", "a.ply", "p.ply"})
    put("fuzz_ply", n, std::string(std::istreambuf_iterator<char>(std::ifstream(tmp / n, std::ios::binary).rdbuf()), {}));
  Npz z;
  z.put("A", Eigen::MatrixXd(Eigen::MatrixXd::Random(3, 2)));
  z.put("i", Eigen::VectorXi(Eigen::VectorXi::LinSpaced(4, 0, 3)));
  z.put_text("meta", "{\"version\": 1}");
  put("fuzz_npz", "model.npz", z.serialize());
  put("fuzz_bvh", "small.bvh",
      "HIERARCHY\nROOT root\n{\n\tOFFSET 0 0 0\n\tCHANNELS 6 Xposition Yposition Zposition "
      "Zrotation Xrotation Yrotation\n\tJOINT child\n\t{\n\t\tOFFSET 0 1 0\n\t\tCHANNELS 3 "
      "Zrotation Xrotation Yrotation\n\t\tEnd Site\n\t\t{\n\t\t\tOFFSET 0 1 0\n\t\t}\n\t}\n}\n"
      "MOTION\nFrames: 2\nFrame Time: 0.0333\n0 0 0 10 20 30 1 2 3\n0 0 0 0 0 0 0 0 0\n");
  // MakeHuman formats (the layout of the CC0 files, tiny).
  put("fuzz_mh_target", "small.target", "# basemesh hm08\n0 0.1 -0.2 .3\n5 1 2 3\n99 -.016 0 1e-3\n");
  const std::string mhskel =
      R"({"name": "t", "bones": {"root": {"head": "j0", "tail": "j1"},)"
      R"( "spine": {"parent": "root", "head": "j1", "tail": "j2"},)"
      R"( "head": {"parent": "spine", "head": "j2", "tail": "j3"}},)"
      R"( "joints": {"j0": [0, 1], "j1": [2], "j2": [3, 4, 5], "j3": [6]}})";
  put("fuzz_mhskel", "small.mhskel", mhskel);
  put("fuzz_mhw", "small.mhw",
      R"({"name": "t", "weights": {"root": [[0, 1.0], [1, 0.5]], "spine": [[1, 0.5], [2, 0.25]],)"
      R"( "head": [[2, 0.75], [3, 1e-5]]}})");
  // MakeHuman assets: a binding (header, scale lines, exact, 6- and 9-number rows, deleted
  // ranges) and a material.
  put("fuzz_mhclo", "small.mhclo",
      "# clothes\nname t\nobj_file t.obj\nx_scale 1 2 1.5\ny_scale 3 4 0.5\nz_scale 5 6 2\nz_depth 50\n"
      "verts 0\nmaterial t.mhmat\n10 11 12 0.2 0.3 0.5 0.01 -0.02 0.03\n7\n20 21 22 0.25 0.25 0.5\n"
      "delete_verts\n1 2 - 5 9\n");
  put("fuzz_mhmat", "small.mhmat",
      "name t\ndiffuseColor 0.8 0.1 0.05\nshininess 0.3\nopacity 1\ntransparent False\n"
      "diffuseTexture t_diffuse.png\nshaderConfig spec True\n");
  // Landmarks and label tables.
  put("fuzz_landmarks", "small.json",
      R"({"head_top": [0, 1700.5, 10], "chin": [1, 1500, 80], "l_knee": [-100, 500, 40]})");
  put("fuzz_labels_csv", "subjects.csv",
      "subject_id,sex,age_years,height_cm,weight_kg,muscle\ns1,female,31,165.2,60,50\n"
      "s2,male,,180.5,80.5,62\n");
  put("fuzz_labels_csv", "scans.csv", "scan_id,subject_id,pose\ns1_p0,s1,standard\ns1_p1,s1,walk\n");
  put("fuzz_pose_csv", "small.pose.csv",
      "bone,rx,ry,rz\n_scale,1.01,0,0\n_root_translation_mm,1,2,3\n_global_rotation,0,0.1,0\n"
      "_global_translation_mm,5,6,7\nroot,0,0,0\nspine,0.1,0.2,0.3\nhead,-0.5,0,0\n");
  // libigl formats.
  put("fuzz_tgf", "small.tgf", "1 0 0 0\n2 0 1 0 0 0 0 0\n3 0 2 0\n#\n1 2 1 0 0\n2 3\n#\n");
  Eigen::MatrixXd T(8, 3);  // two bones' stacked transforms [R^T; t^T]
  T << 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -1, 0, 0, 0, 0, 1, 1, 2, 3;
  auto file_bytes = [&](const fs::path& p) {
    return std::string(std::istreambuf_iterator<char>(std::ifstream(p, std::ios::binary).rdbuf()), {});
  };
  write_dmat(tmp / "a.dmat", T, true);
  write_dmat(tmp / "b.dmat", T, false);
  Eigen::MatrixXd anim(24, 2);  // two frames of that stack, column-major
  anim.col(0) = Eigen::Map<const Eigen::VectorXd>(T.data(), 24);
  anim.col(1) = anim.col(0) * 0.5;
  write_dmat(tmp / "c.dmat", anim, true);
  put("fuzz_dmat", "ascii.dmat", file_bytes(tmp / "a.dmat"));
  put("fuzz_dmat", "binary.dmat", file_bytes(tmp / "b.dmat"));
  put("fuzz_dmat", "anim.dmat", file_bytes(tmp / "c.dmat"));
  put("fuzz_dmat", "two.Tmat", "1 0 0\n0 1 0\n0 0 1\n0 0 0\n0 1 0\n-1 0 0\n0 0 1\n1 2 3\n");
  // A skinning rig (SSD, 4 vertices, 2 bones) with one fitted pose, without and with a skeleton.
  tiny::write_rig(tmp / "rig.npz", false);
  put("fuzz_rig_npz", "ssd.npz", file_bytes(tmp / "rig.npz"));
  tiny::write_rig(tmp / "rig.npz", true);
  put("fuzz_rig_npz", "ssd_skeleton.npz", file_bytes(tmp / "rig.npz"));
  // A model file in the real format with tiny arrays.
  put("fuzz_model_npz", "tetra.npz", tiny::model_npz().serialize());
  // An encoding file (`bodymodel encode`): the tetrahedron, two rows, names with a path in one.
  {
    EncodingFile e;
    e.template_vertices = tiny::tetra_vertices();
    e.template_faces = tiny::tetra_faces();
    e.encodings = Eigen::MatrixXd::Zero(2, 60);
    e.mean = Eigen::VectorXd::Zero(60);
    e.names = {"rest", "../up/walk"};
    put("fuzz_encoding_npz", "two.npz", encoding_to_npz(e, "layout").serialize());
  }
  // Marker captures: 3 markers (one unlabelled piece), 4 frames, one sample missing; C3D in every
  // processor type and storage, TRC.
  {
    MarkerData d;
    d.labels = {"LASI", "RASI", "*1"};
    d.rate = 120;
    d.xyz = Eigen::MatrixXd::Constant(4, 9, 12.5);
    d.clear(2, 1);
    for (auto proc : {C3dProcessor::intel, C3dProcessor::dec, C3dProcessor::mips})
      for (bool floating : {true, false})
        put("fuzz_c3d", "p" + std::to_string(int(proc)) + (floating ? "_float.c3d" : "_int.c3d"),
            c3d_bytes(d, {proc, floating, 0.25}));
    put("fuzz_trc", "three.trc", trc_text(d));
  }
  fs::remove_all(tmp);
  std::cout << "seeds written to " << dir << "\n";
  return 0;
}
