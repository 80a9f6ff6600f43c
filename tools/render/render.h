// Headless software rendering of meshes and point clouds to PNG (z-buffer rasteriser,
// orthographic camera, Gouraud-shaded Lambert lighting, per-vertex colours). No GPU, no
// display: pictures for reports and the README.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace bodymodel {

struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;  // width × height × 3, row-major from the top
  Image() = default;
  Image(int w, int h, uint8_t background = 255) : width(w), height(h), rgb(size_t(w) * h * 3, background) {}
  // Writes PNG atomically (InputError naming the file on failure).
  void save_png(const std::filesystem::path& path) const;
  // Copies `other` with its top-left corner at (x, y).
  void paste(const Image& other, int x, int y);
};

struct Camera {
  Eigen::Vector3d forward{0, 0, -1};  // viewing direction (default: looking at the front of a +z-facing body)
  Eigen::Vector3d up{0, 1, 0};
  // World-space box the picture frames; empty (min > max) = fit to the geometry.
  Eigen::Vector3d frame_min{1, 1, 1}, frame_max{-1, -1, -1};
  double margin = 0.04;               // fraction of the picture left empty around the geometry
};

// Renders a triangle mesh. V #V by 3, F #F by 3; colors #V by 3 in [0, 1] or empty (light grey).
Image render_mesh(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const Eigen::MatrixX3d& colors,
                  int width, int height, const Camera& camera = {});
// Renders points as small discs shaded by their normals (N may be empty).
Image render_points(const Eigen::MatrixX3d& P, const Eigen::MatrixX3d& N, int width, int height,
                    const Camera& camera = {});

// Several meshes side by side in one row, at a common scale and floor.
Image render_row(const std::vector<Eigen::MatrixX3d>& meshes, const Eigen::MatrixX3i& F,
                 const std::vector<Eigen::MatrixX3d>& colors, int cell_width, int height,
                 const Camera& camera = {});

// A mesh with its own triangles and per-vertex colours (e.g. a dressed character, its parts
// concatenated); colors #V by 3 in [0, 1] or empty (light grey).
struct ColouredMesh {
  Eigen::MatrixX3d V;
  Eigen::MatrixX3i F;
  Eigen::MatrixX3d colors;
};
// render_row for meshes with different triangles (one scale and floor for all).
Image render_row(const std::vector<ColouredMesh>& meshes, int cell_width, int height, const Camera& camera = {});

// Colour map for errors and other scalars: values mapped linearly from [vmin, vmax] through
// blue → cyan → green → yellow → red (clamped). Returns #values by 3 in [0, 1].
Eigen::MatrixX3d heat_colors(const Eigen::VectorXd& values, double vmin, double vmax);
// A horizontal colour bar (for a legend) of the same map.
Image heat_colorbar(int width, int height);

}  // namespace bodymodel
