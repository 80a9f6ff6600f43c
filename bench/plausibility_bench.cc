// Self-intersection count of a crowd's bodies: the grid broad phase (core/plausibility.h)
// against CGAL's box_self_intersection_d with the cutoff the library used before (2000) and
// with CGAL's default cutoff (10, the first version), in one process. Prints the CPU per body
// of each, their ratios to the default-cutoff baseline, and whether every body's count agrees.
//   build/bench/plausibility_bench CROWD_FOLDER   (body_NNN.obj from `bodymodel generate`)
#include <fmt/format.h>

#include <ctime>
#include <filesystem>
#include <vector>

#include "core/io/mesh_io.h"
#include "core/plausibility.h"

using namespace bodymodel;

int main(int argc, char** argv) {
  if (argc != 2) {
    fmt::print(stderr, "usage: plausibility_bench CROWD_FOLDER\n");
    return 2;
  }
  std::vector<Mesh> meshes;
  for (int i = 0;; ++i) {
    const auto p = std::filesystem::path(argv[1]) / fmt::format("body_{:03d}.obj", i);
    if (!std::filesystem::exists(p)) break;
    meshes.push_back(read_mesh(p));
  }
  if (meshes.empty()) {
    fmt::print(stderr, "{}: no body_000.obj\n", argv[1]);
    return 2;
  }
  auto run = [&](auto fn, std::vector<int>& counts) {
    const std::clock_t t0 = std::clock();
    for (auto& m : meshes) counts.push_back(fn(m.V, m.F));
    return double(std::clock() - t0) / CLOCKS_PER_SEC / meshes.size();
  };
  std::vector<int> base, box, grid;
  const double t_base = run([](const auto& V, const auto& F) { return self_intersecting_triangle_pairs_box_d(V, F, 10); }, base);
  const double t_box = run([](const auto& V, const auto& F) { return self_intersecting_triangle_pairs_box_d(V, F); }, box);
  const double t_grid = run([](const auto& V, const auto& F) { return self_intersecting_triangle_pairs(V, F); }, grid);
  long total = 0;
  for (int c : base) total += c;
  fmt::print("{} bodies, {} crossing pairs in all\n", meshes.size(), total);
  fmt::print("CGAL box intersection, cutoff 10   {:.1f} ms CPU per body (baseline)\n", 1e3 * t_base);
  fmt::print("CGAL box intersection, cutoff 2000 {:.1f} ms ({:.2f}x), counts {}\n", 1e3 * t_box, t_box / t_base,
             box == base ? "equal" : "DIFFER");
  fmt::print("uniform grid                       {:.1f} ms ({:.2f}x), counts {}\n", 1e3 * t_grid, t_grid / t_base,
             grid == base ? "equal" : "DIFFER");
  return grid == base && box == base ? 0 : 1;
}
