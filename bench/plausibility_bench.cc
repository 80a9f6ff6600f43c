// Self-intersection count of a crowd's bodies: the grid broad phase (core/plausibility.h)
// against CGAL's box_self_intersection_d with the cutoff the library used before (2000) and
// with CGAL's default cutoff (10, the first version), in one process. Prints the CPU per body
// of each, their ratios to the default-cutoff baseline, and whether every body's count agrees.
//   build/bench/plausibility_bench CROWD_FOLDER   (body_NNN.obj from `bodymodel generate`)
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Box_intersection_d/Box_with_info_d.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>
#include <fmt/format.h>

#include <ctime>
#include <filesystem>
#include <vector>

#include "core/io/mesh_io.h"
#include "core/plausibility.h"

using namespace bodymodel;

namespace {

// The first version: CGAL's box intersection with its default cutoff.
int default_cutoff_count(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F) {
  using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 3, int, CGAL::Box_intersection_d::ID_EXPLICIT>;
  std::vector<Box> boxes;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    double lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min({V(F(f, 0), k), V(F(f, 1), k), V(F(f, 2), k)});
      hi[k] = std::max({V(F(f, 0), k), V(F(f, 1), k), V(F(f, 2), k)});
    }
    boxes.emplace_back(lo, hi, static_cast<int>(f));
  }
  auto point = [&](int v) { return Kernel::Point_3(V(v, 0), V(v, 1), V(v, 2)); };
  int count = 0;
  CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), [&](const Box& a, const Box& b) {
    const int fa = a.info(), fb = b.info();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        if (F(fa, i) == F(fb, j)) return;
    const Kernel::Triangle_3 ta(point(F(fa, 0)), point(F(fa, 1)), point(F(fa, 2)));
    const Kernel::Triangle_3 tb(point(F(fb, 0)), point(F(fb, 1)), point(F(fb, 2)));
    if (!ta.is_degenerate() && !tb.is_degenerate() && CGAL::do_intersect(ta, tb)) ++count;
  });
  return count;
}

}  // namespace

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
  const double t_base = run(default_cutoff_count, base);
  const double t_box = run(self_intersecting_triangle_pairs_box_d, box);
  const double t_grid = run(self_intersecting_triangle_pairs, grid);
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
