// Shared helpers of the `bodymodel skin ...` verbs: the `skin` verb group, reading a folder of
// frames, colouring per-vertex errors.
#pragma once

#include <CLI/CLI.hpp>
#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/io/mesh_io.h"
#include "core/mesh.h"

namespace bodymodel::cli {

// The `skin` group, created by whichever skinning verb registers first.
inline CLI::App* skin_group(CLI::App& app) {
  for (CLI::App* s : app.get_subcommands(std::function<bool(CLI::App*)>()))
    if (s->get_name() == "skin") return s;
  CLI::App* s = app.add_subcommand("skin", "Skinning rigs: fit SSD / Animation Space / MWE to example "
                                           "poses, evaluate them (Jacka et al. 2007), apply them");
  s->require_subcommand(1);
  return s;
}

struct MeshSequence {
  std::vector<std::string> names;           // file stems, sorted
  std::vector<Eigen::MatrixX3d> frames;     // #frames, #V by 3
  Eigen::MatrixX3i F;                       // shared faces (the first frame's)
  std::vector<Eigen::MatrixX3i> frame_faces;   // per frame, only when they differ and were allowed
};

inline bool is_mesh_file_name(const std::filesystem::path& p) {
  auto ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  return ext == ".obj" || ext == ".ply" || ext == ".off";
}

// The given files in the given order; all must share the first file's vertex count and faces,
// and their names (file names without extension) must differ. With `per_frame_faces`, frames may
// triangulate the corresponding vertices differently (SCAPE): each keeps its own faces.
inline MeshSequence read_mesh_files(const std::vector<std::filesystem::path>& files, bool per_frame_faces = false);

// Every .obj / .ply / .off in `dir`, sorted by name; all must share the first file's vertex count
// and faces.
inline MeshSequence read_mesh_sequence(const std::filesystem::path& dir, bool per_frame_faces = false) {
  if (!std::filesystem::is_directory(dir))
    throw InputError(dir.string() + ": expected a folder of .obj/.ply/.off frames");
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.is_regular_file() && is_mesh_file_name(e.path())) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  if (files.empty()) throw InputError(dir.string() + ": no .obj, .ply or .off frames in the folder");
  return read_mesh_files(files, per_frame_faces);
}

inline MeshSequence read_mesh_files(const std::vector<std::filesystem::path>& files, bool per_frame_faces) {
  if (files.empty()) throw InputError("no mesh files given");
  MeshSequence seq;
  for (const auto& f : files) {
    Mesh m = read_mesh(f);
    if (seq.frames.empty()) {
      seq.F = m.F;
    } else {
      if (m.V.rows() != seq.frames[0].rows())
        throw InputError(f.string() + ": " + std::to_string(m.V.rows()) + " vertices, expected " +
                         std::to_string(seq.frames[0].rows()) + " like " + files[0].string());
      if (!per_frame_faces && (m.F.rows() != seq.F.rows() || m.F != seq.F))
        throw InputError(f.string() + ": its faces differ from " + files[0].string() +
                         " (a sequence must share one connectivity; --per-frame-faces accepts frames whose vertices "
                         "correspond but are triangulated differently)");
    }
    if (std::find(seq.names.begin(), seq.names.end(), f.stem().string()) != seq.names.end())
      throw InputError(f.string() + ": a second frame named '" + f.stem().string() +
                       "' (frames are named by file name without extension)");
    seq.names.push_back(f.stem().string());
    seq.frames.push_back(std::move(m.V));
    seq.frame_faces.push_back(std::move(m.F));
  }
  bool differ = false;
  for (const auto& Ff : seq.frame_faces) differ = differ || Ff.rows() != seq.F.rows() || Ff != seq.F;
  if (!differ) seq.frame_faces.clear();
  return seq;
}

// Fixed colour scale: 0 → blue, scale/2 → green, ≥ scale → red (linear in between).
inline Eigen::MatrixX3d error_colors(const Eigen::VectorXd& e, double scale) {
  Eigen::MatrixX3d C(e.size(), 3);
  for (Eigen::Index i = 0; i < e.size(); ++i) {
    const double t = std::clamp(scale > 0 ? e(i) / scale : 0.0, 0.0, 1.0);
    if (t < 0.5) C.row(i) << 0.0, 2 * t, 1 - 2 * t;
    else C.row(i) << 2 * t - 1, 2 - 2 * t, 0.0;
  }
  return C;
}

}  // namespace bodymodel::cli
