// Writes small seed inputs for every fuzz target into <dir>/<target>/ (made in code: no copies
// of the shared data).
#include <filesystem>
#include <fstream>
#include <iostream>

#include "core/io/bvh.h"
#include "core/io/mesh_io.h"
#include "core/io/npz.h"

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
  put("fuzz_obj", "quads.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\ng body\nf 1/1/1 2/2/2 3/3/3 4/4/4\nf -1 -2 -3\n");
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
  fs::remove_all(tmp);
  std::cout << "seeds written to " << dir << "\n";
  return 0;
}
