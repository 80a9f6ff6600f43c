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
  Eigen::MatrixX3i F;                       // shared faces
};

// Every .obj / .ply in `dir`, sorted by name; all must share the first file's vertex count and faces.
inline MeshSequence read_mesh_sequence(const std::filesystem::path& dir) {
  if (!std::filesystem::is_directory(dir))
    throw InputError(dir.string() + ": expected a folder of .obj/.ply frames");
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    auto ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    if (e.is_regular_file() && (ext == ".obj" || ext == ".ply")) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) throw InputError(dir.string() + ": no .obj or .ply frames in the folder");
  MeshSequence seq;
  for (const auto& f : files) {
    Mesh m = read_mesh(f);
    if (seq.frames.empty()) {
      seq.F = m.F;
    } else {
      if (m.V.rows() != seq.frames[0].rows())
        throw InputError(f.string() + ": " + std::to_string(m.V.rows()) + " vertices, expected " +
                         std::to_string(seq.frames[0].rows()) + " like " + files[0].string());
      if (m.F.rows() != seq.F.rows() || m.F != seq.F)
        throw InputError(f.string() + ": its faces differ from " + files[0].string() +
                         " (a sequence must share one connectivity)");
    }
    seq.names.push_back(f.stem().string());
    seq.frames.push_back(std::move(m.V));
  }
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
