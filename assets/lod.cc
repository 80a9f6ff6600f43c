#include "assets/lod.h"

#include <fmt/format.h>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Bounded_distance_placement.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Count_ratio_stop_predicate.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/LindstromTurk_cost.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/LindstromTurk_placement.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <algorithm>
#include <array>
#include <cmath>
#include <map>

#include "core/error.h"
#include "core/geometry.h"

namespace bodymodel {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using CgalMesh = CGAL::Surface_mesh<Point>;
namespace PMP = CGAL::Polygon_mesh_processing;
namespace SMS = CGAL::Surface_mesh_simplification;

// The faces of F over the vertices they use (renumbered); `map` (optional) gets old → new (-1).
SimplifiedMesh compact(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, std::vector<int>* map_out = nullptr) {
  std::vector<int> map(V.rows(), -1);
  int n = 0;
  for (Eigen::Index i = 0; i < F.size(); ++i)
    if (map[F.data()[i]] < 0) map[F.data()[i]] = n++;
  SimplifiedMesh m;
  m.V.resize(n, 3);
  for (Eigen::Index v = 0; v < V.rows(); ++v)
    if (map[v] >= 0) m.V.row(map[v]) = V.row(v);
  m.F.resize(F.rows(), 3);
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k) m.F(f, k) = map[F(f, k)];
  if (map_out) *map_out = std::move(map);
  return m;
}

}  // namespace

int triangle_count(const std::vector<DressedPart>& parts) {
  int n = 0;
  for (const DressedPart& p : parts) n += static_cast<int>(p.F.rows());
  return n;
}

SimplifiedMesh simplify_mesh(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, int target_triangles,
                             double max_error) {
  if (V.rows() == 0 || F.rows() == 0) throw InputError("simplify_mesh: the mesh is empty");
  if (target_triangles < 1) throw InputError(fmt::format("simplify_mesh: target of {} triangles", target_triangles));
  if (F.rows() <= target_triangles) return compact(V, F);
  std::vector<Point> points;
  for (Eigen::Index v = 0; v < V.rows(); ++v) points.emplace_back(V(v, 0), V(v, 1), V(v, 2));
  std::vector<std::array<std::size_t, 3>> soup;
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    soup.push_back({std::size_t(F(f, 0)), std::size_t(F(f, 1)), std::size_t(F(f, 2))});
  // MakeHuman's assets are not all manifold (hair cards, shared edges): split into manifold
  // pieces, which edge collapse needs.
  PMP::repair_polygon_soup(points, soup);
  PMP::orient_polygon_soup(points, soup);
  CgalMesh mesh;
  PMP::polygon_soup_to_polygon_mesh(points, soup, mesh);
  const double faces = static_cast<double>(mesh.number_of_faces());
  if (faces > target_triangles) {
    // The stop predicate counts edges; on a triangle mesh they scale with the faces.
    SMS::Count_ratio_stop_predicate<CgalMesh> stop(target_triangles / faces);
    const SMS::LindstromTurk_cost<CgalMesh> cost;
    if (max_error > 0) {
      // Hair cards and thin shells let Lindstrom–Turk place vertices centimetres off the input.
      const SMS::Bounded_distance_placement<SMS::LindstromTurk_placement<CgalMesh>, Kernel> placement(max_error);
      SMS::edge_collapse(mesh, stop, CGAL::parameters::get_cost(cost).get_placement(placement));
    } else {
      SMS::edge_collapse(mesh, stop);
    }
  }
  mesh.collect_garbage();
  SimplifiedMesh out;
  out.V.resize(mesh.number_of_vertices(), 3);
  for (const auto v : mesh.vertices()) {
    const Point& p = mesh.point(v);
    out.V.row(static_cast<Eigen::Index>(v.idx())) << p.x(), p.y(), p.z();
  }
  out.F.resize(mesh.number_of_faces(), 3);
  Eigen::Index f = 0;
  for (const auto face : mesh.faces()) {
    int k = 0;
    for (const auto v : CGAL::vertices_around_face(mesh.halfedge(face), mesh)) out.F(f, k++) = static_cast<int>(v.idx());
    ++f;
  }
  return out;
}

DressedPart simplified_part(const DressedPart& source, int target_triangles, double max_error) {
  DressedPart p = source;
  const SimplifiedMesh m = simplify_mesh(source.V, source.F, target_triangles, max_error);
  p.V = m.V;
  p.F = m.F;
  p.weights = skin_weights_at(p.V, source.V, source.F, source.weights);
  p.before = p.after = Penetration{};
  return p;
}

ProxySurface proxy_surface(const Asset& proxy, const DressedSkinBody& dressed) {
  const AssetBinding& b = proxy.binding;
  ProxySurface s;
  s.V = fit_asset(b, dressed.full_rest);
  s.F = proxy.faces;
  s.weights = asset_skin_weights(b, dressed.full_weights);
  s.hidden.assign(static_cast<size_t>(s.V.rows()), 0);
  for (Eigen::Index i = 0; i < s.V.rows(); ++i) {
    Eigen::Index k;
    b.weights.row(i).cwiseAbs().maxCoeff(&k);
    s.hidden[i] = dressed.full_hidden.at(static_cast<size_t>(b.vertices(i, k)));
  }
  return s;
}

DressedPart proxy_body_part(const Asset& proxy, const DressedSkinBody& dressed, const DressedPart& body) {
  const ProxySurface s = proxy_surface(proxy, dressed);
  const Eigen::MatrixX3d& V = s.V;
  const SkinWeights& W = s.weights;
  const std::vector<char>& hidden = s.hidden;
  // A proxy face is far larger than the body's: dropping it when one corner is hidden (as
  // visible_faces does for the body) opens gaps between garments, so only faces hidden at every
  // corner go.
  std::vector<int> keep;
  for (Eigen::Index f = 0; f < proxy.faces.rows(); ++f)
    if (!(hidden[proxy.faces(f, 0)] && hidden[proxy.faces(f, 1)] && hidden[proxy.faces(f, 2)])) keep.push_back(int(f));
  std::vector<int> map;
  const SimplifiedMesh m = compact(V, proxy.faces(keep, Eigen::all), &map);
  DressedPart p;
  p.name = body.name;
  p.kind = body.kind;
  p.colour = body.colour;
  p.roughness = body.roughness;
  p.V = m.V;
  p.F = m.F;
  std::vector<Eigen::Triplet<double>> t;
  for (Eigen::Index v = 0; v < V.rows(); ++v)
    if (map[v] >= 0)
      for (SkinWeights::InnerIterator it(W, v); it; ++it) t.emplace_back(map[v], it.col(), it.value());
  p.weights.resize(m.V.rows(), W.cols());
  p.weights.setFromTriplets(t.begin(), t.end());
  return p;
}

std::vector<DressedPart> level_of_detail(const std::vector<DressedPart>& parts, const DressedSkinBody& dressed,
                                         const LodSpec& spec) {
  if (parts.empty() || parts[0].kind != "body") throw InputError("level_of_detail: the first part must be the body");
  constexpr int kMinPart = 24;
  std::vector<const DressedPart*> kept;
  for (size_t i = 1; i < parts.size(); ++i)
    if (std::find(spec.drop_kinds.begin(), spec.drop_kinds.end(), parts[i].kind) == spec.drop_kinds.end())
      kept.push_back(&parts[i]);
  if (spec.max_triangles < kMinPart * static_cast<int>(kept.size() + 1))
    throw InputError(fmt::format("level_of_detail: {} triangles for {} parts", spec.max_triangles, kept.size() + 1));
  std::vector<DressedPart> level = {spec.proxy ? proxy_body_part(*spec.proxy, dressed, parts[0]) : parts[0]};
  if (!spec.proxy || level[0].F.rows() > spec.max_triangles / 2) {
    const int body_share = spec.proxy ? spec.max_triangles / 2 : 0;
    if (body_share > 0) level[0] = simplified_part(level[0], body_share, spec.max_error_mm);
    else kept.insert(kept.begin(), &parts[0]), level.clear();
  }
  std::vector<double> area;
  double total_area = 0;
  for (const DressedPart* p : kept) total_area += area.emplace_back(face_areas(p->V, p->F).sum());
  const int fixed = triangle_count(level);
  // Edge collapse lands near, not on, each target: shrink the shares until the level fits.
  double budget = spec.max_triangles - fixed;
  for (int round = 0; round < 8; ++round) {
    std::vector<DressedPart> out = level;
    for (size_t i = 0; i < kept.size(); ++i) {
      const int share = std::max(kMinPart, static_cast<int>(std::floor(budget * area[i] / total_area)));
      out.push_back(kept[i]->F.rows() <= share ? *kept[i] : simplified_part(*kept[i], share, spec.max_error_mm));
    }
    const int n = triangle_count(out);
    if (n <= spec.max_triangles) return out;
    budget *= 0.97 * (spec.max_triangles - fixed) / std::max(1.0, double(n - fixed));
  }
  throw NumericalError(fmt::format("level_of_detail: could not fit {} triangles", spec.max_triangles));
}

}  // namespace bodymodel
