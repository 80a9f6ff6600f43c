#include "core/measure.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/convex_hull_2.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <vector>

#include "core/error.h"
#include "core/geometry.h"
#include "core/landmarks.h"

namespace bodymodel {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point2 = Kernel::Point_2;

inline uint64_t edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<uint64_t>(static_cast<uint32_t>(a)) << 32) | static_cast<uint32_t>(b);
}

// Closed loops of the section of the mesh (the triangles `faces`, or all when null) with the
// plane (x − origin)·normal = 0, as 2-D polygons in the in-plane axes (u, w) relative to
// `origin`. Open chains (non-closed meshes, or a face subset cut short) are returned too.
std::vector<std::vector<Eigen::Vector2d>> section_loops(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                                                        const std::vector<int>* faces,
                                                        const Eigen::Vector3d& origin, const Eigen::Vector3d& normal,
                                                        const Eigen::Vector3d& u, const Eigen::Vector3d& w) {
  // Each crossing triangle gives a segment between two edge points; link segments by edge.
  std::unordered_map<uint64_t, Eigen::Vector2d> point_of_edge;
  std::unordered_map<uint64_t, std::vector<uint64_t>> links;
  auto distance = [&](int v) { return (V.row(v).transpose() - origin).dot(normal); };
  const Eigen::Index face_count = faces ? static_cast<Eigen::Index>(faces->size()) : F.rows();
  for (Eigen::Index k0 = 0; k0 < face_count; ++k0) {
    const Eigen::Index f = faces ? (*faces)[k0] : k0;
    uint64_t ends[2];
    int n = 0;
    const double d[3] = {distance(F(f, 0)), distance(F(f, 1)), distance(F(f, 2))};
    for (int k = 0; k < 3; ++k) {
      const int a = k, b = (k + 1) % 3;
      if ((d[a] >= 0) == (d[b] >= 0)) continue;
      const int i = F(f, a), j = F(f, b);
      const double t = d[a] / (d[a] - d[b]);
      const Eigen::Vector3d p = V.row(i).transpose() + t * (V.row(j) - V.row(i)).transpose() - origin;
      uint64_t key = edge_key(i, j);
      point_of_edge.emplace(key, Eigen::Vector2d(p.dot(u), p.dot(w)));
      if (n < 2) ends[n++] = key;
    }
    if (n == 2) {
      links[ends[0]].push_back(ends[1]);
      links[ends[1]].push_back(ends[0]);
    }
  }
  std::vector<std::vector<Eigen::Vector2d>> loops;
  std::unordered_map<uint64_t, bool> used;
  for (auto& [start, _] : links) {
    if (used[start]) continue;
    std::vector<Eigen::Vector2d> loop;
    uint64_t prev = ~0ull, cur = start;
    while (!used[cur]) {
      used[cur] = true;
      loop.push_back(point_of_edge[cur]);
      uint64_t next = ~0ull;
      for (uint64_t nb : links[cur])
        if (nb != prev && !used[nb]) { next = nb; break; }
      if (next == ~0ull) break;
      prev = cur;
      cur = next;
    }
    if (loop.size() >= 3) loops.push_back(std::move(loop));
  }
  return loops;
}

// The same for the horizontal plane x[up] = h, in the two remaining coordinates.
std::vector<std::vector<Eigen::Vector2d>> section_loops(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                                                        double h, int up, const std::vector<int>* faces = nullptr) {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero(), normal = Eigen::Vector3d::Zero();
  origin(up) = h;
  normal(up) = 1;
  return section_loops(V, F, faces, origin, normal, Eigen::Vector3d::Unit((up + 1) % 3),
                       Eigen::Vector3d::Unit((up + 2) % 3));
}

double polygon_area(const std::vector<Eigen::Vector2d>& p) {
  double a = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    const auto& u = p[i];
    const auto& w = p[(i + 1) % p.size()];
    a += u.x() * w.y() - w.x() * u.y();
  }
  return std::abs(a) / 2;
}

double hull_perimeter(const std::vector<Eigen::Vector2d>& loop) {
  std::vector<Point2> pts, hull;
  pts.reserve(loop.size());
  for (auto& p : loop) pts.emplace_back(p.x(), p.y());
  CGAL::convex_hull_2(pts.begin(), pts.end(), std::back_inserter(hull));
  double per = 0;
  for (size_t i = 0; i < hull.size(); ++i)
    per += std::sqrt(CGAL::squared_distance(hull[i], hull[(i + 1) % hull.size()]));
  return per;
}

const std::vector<Eigen::Vector2d>* largest_loop(const std::vector<std::vector<Eigen::Vector2d>>& loops) {
  const std::vector<Eigen::Vector2d>* best = nullptr;
  double best_area = -1;
  for (auto& l : loops) {
    double a = polygon_area(l);
    if (a > best_area) { best_area = a; best = &l; }
  }
  return best;
}

Eigen::Vector3d landmark_point(const Eigen::MatrixX3d& V, const std::vector<int>& vertices) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int v : vertices) p += V.row(v).transpose();
  return p / static_cast<double>(vertices.size());
}

// Triangles whose extent along `up` overlaps [a, b].
std::vector<int> faces_spanning(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, int up, double a, double b) {
  std::vector<int> out;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const double p = V(F(f, 0), up), q = V(F(f, 1), up), r = V(F(f, 2), up);
    if (std::max({p, q, r}) >= a && std::min({p, q, r}) <= b) out.push_back(static_cast<int>(f));
  }
  return out;
}

// The survey measurements (header comment) of a template-topology body; `lo` = lowest point
// along up. Fills m's survey fields and hips_cm / hips_at_cm.
void measure_survey(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, const MeasureOptions& o, double lo,
                    BodyMeasurements& m) {
  const SurveyLandmarks& L = survey_landmarks();
  const int up = o.up_axis;
  const double to_cm = o.mm_per_unit / 10.0, mm = 1.0 / o.mm_per_unit;  // mm in mesh units
  const Eigen::Vector3d e_up = Eigen::Vector3d::Unit(up);
  const Eigen::Vector3d u = Eigen::Vector3d::Unit((up + 1) % 3), w = Eigen::Vector3d::Unit((up + 2) % 3);
  auto horizontal = [&](Eigen::Vector3d v) { return Eigen::Vector3d(v - v.dot(e_up) * e_up); };

  // Waist at the iliac crest.
  const double crest = landmark_point(V, L.iliac_crest)(up);
  {
    const std::vector<int> faces = faces_spanning(V, F, up, crest, crest);
    const auto loops = section_loops(V, F, crest, up, &faces);
    if (const auto* l = largest_loop(loops)) {
      m.waist_iliac_cm = hull_perimeter(*l) * to_cm;
      m.waist_iliac_at_cm = (crest - lo) * to_cm;
    }
  }

  // Hip: the level of the maximum posterior extension of the buttocks, searched in the lower part
  // of the crotch → iliac crest span (MeasureOptions::hip_band_fraction). Posterior = minus the
  // body's forward direction (left-right axis × up).
  {
    const Eigen::Vector3d left = horizontal(V.row(L.hip_l).transpose() - V.row(L.hip_r).transpose());
    Eigen::Vector3d forward = left.cross(e_up);
    const Eigen::Vector3d mid = 0.5 * (V.row(L.hip_l) + V.row(L.hip_r)).transpose();
    if ((V.row(L.navel).transpose() - mid).dot(forward) < 0) forward = -forward;
    const Eigen::Vector2d back2 = -Eigen::Vector2d(forward.dot(u), forward.dot(w)).normalized();
    const double crotch = landmark_point(V, L.crotch)(up);
    const double bottom = crotch + 10 * mm, top = crotch + o.hip_band_fraction * (crest - crotch);
    const int n = std::max(2, o.hip_slices);
    if (top > bottom && left.norm() > 0) {
      std::vector<double> extension(n, -std::numeric_limits<double>::infinity()), girth(n, 0), at(n, 0);
      for (int s = 0; s < n; ++s) at[s] = bottom + (top - bottom) * s / (n - 1);
      // Each cut only looks at the triangles whose vertical extent contains its height.
      std::vector<std::vector<int>> cut_faces(n);
      for (int f : faces_spanning(V, F, up, bottom, top)) {
        const double p = V(F(f, 0), up), q = V(F(f, 1), up), r = V(F(f, 2), up);
        const auto first = std::lower_bound(at.begin(), at.end(), std::min({p, q, r}));
        const auto last = std::upper_bound(first, at.end(), std::max({p, q, r}));
        for (auto it = first; it != last; ++it) cut_faces[it - at.begin()].push_back(f);
      }
      std::vector<std::vector<Eigen::Vector2d>> torso(n);
      for (int s = 0; s < n; ++s) {
        auto loops = section_loops(V, F, at[s], up, &cut_faces[s]);
        if (const auto* l = largest_loop(loops)) torso[s] = *l;
        for (const auto& p : torso[s]) extension[s] = std::max(extension[s], p.dot(back2));
      }
      const double most = *std::max_element(extension.begin(), extension.end());
      int best = -1;
      for (int s = 0; s < n; ++s)
        if (std::isfinite(extension[s]) && extension[s] >= most - o.hip_extension_tolerance_mm * mm) {
          girth[s] = hull_perimeter(torso[s]);
          if (best < 0 || girth[s] > girth[best]) best = s;
        }
      if (best >= 0) {
        m.hips_cm = girth[best] * to_cm;
        m.hips_at_cm = (at[best] - lo) * to_cm;
      }
    }
  }

  // Arm circumference: the template's edge ring round the right upper arm at its middle,
  // projected onto the plane perpendicular to acromion → olecranon (a tape held square to the
  // arm); the ring follows the arm, never the torso it may press into.
  const Eigen::Vector3d acromion = landmark_point(V, L.acromion), olecranon = landmark_point(V, L.olecranon);
  m.upper_arm_length_cm = (olecranon - acromion).norm() * to_cm;
  if ((olecranon - acromion).norm() > 0) {
    const Eigen::Vector3d n = (olecranon - acromion).normalized();
    Eigen::Vector3d a = n.cross(e_up);
    if (a.norm() < 1e-6) a = n.cross(u);
    a.normalize();
    const Eigen::Vector3d b = n.cross(a);
    std::vector<Eigen::Vector2d> ring;
    for (int v : L.upper_arm_ring) {
      const Eigen::Vector3d p = V.row(v).transpose() - acromion;
      ring.emplace_back(p.dot(a), p.dot(b));
    }
    m.arm_circumference_cm = hull_perimeter(ring) * to_cm;
  }
  m.upper_leg_length_cm = (landmark_point(V, L.inguinal) - landmark_point(V, L.patella_top)).norm() * to_cm;
  m.survey = true;
}

}  // namespace

const std::vector<MeasurementDefinition>& measurement_definitions() {
  static const std::vector<MeasurementDefinition> table = {
      {"height_cm", "cm", "standing height: extent of the body along the up axis"},
      {"weight_kg", "kg", "enclosed volume (divergence theorem) x 1.01 kg/L"},
      {"volume_l", "L", "enclosed volume (divergence theorem)"},
      {"waist_iliac_cm", "cm",
       "NHANES waist: horizontal girth at the right iliac crest (template landmark, 0.58 of the default body's "
       "stature)"},
      {"hips_cm", "cm",
       "NHANES hip: horizontal girth at the level of the maximum posterior extension of the buttocks, searched in "
       "the lower half of the crotch-iliac crest span"},
      {"arm_circumference_cm", "cm",
       "NHANES mid upper arm circumference (right): girth perpendicular to the acromion-olecranon line at its "
       "midpoint"},
      {"upper_arm_length_cm", "cm", "NHANES upper arm length (right): acromion to olecranon, straight line"},
      {"upper_leg_length_cm", "cm",
       "NHANES upper leg length (right): inguinal crease to the top of the patella, straight line"},
      {"waist_cm", "cm", "natural waist: the smallest torso girth between 0.55 and 0.67 of the height"},
      {"chest_cm", "cm", "largest torso girth between 0.68 and 0.80 of the height, below the armpits"},
      {"neck_cm", "cm", "smallest girth between 0.80 and 0.88 of the height"},
      {"body_fat_pct", "%", "U.S. Navy circumference formula (Hodgdon & Beckett 1984), needs the sex"},
  };
  return table;
}

double measurement_value(const BodyMeasurements& m, const std::string& name) {
  if (name == "height_cm") return m.height_cm;
  if (name == "weight_kg") return m.weight_kg;
  if (name == "volume_l") return m.volume_l;
  if (name == "waist_iliac_cm") return m.waist_iliac_cm;
  if (name == "hips_cm") return m.hips_cm;
  if (name == "arm_circumference_cm") return m.arm_circumference_cm;
  if (name == "upper_arm_length_cm") return m.upper_arm_length_cm;
  if (name == "upper_leg_length_cm") return m.upper_leg_length_cm;
  if (name == "waist_cm") return m.waist_cm;
  if (name == "chest_cm") return m.chest_cm;
  if (name == "neck_cm") return m.neck_cm;
  if (name == "body_fat_pct") return m.body_fat_pct;
  return std::numeric_limits<double>::quiet_NaN();
}

double girth_at_height(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, double h,
                       int up_axis) {
  auto loops = section_loops(V, F, h, up_axis);
  const std::vector<Eigen::Vector2d>* best = largest_loop(loops);
  return best ? hull_perimeter(*best) : 0.0;
}

double navy_body_fat_pct(Sex sex, double height_cm, double neck_cm, double waist_cm,
                         double hips_cm) {
  constexpr double in = 1 / 2.54;
  if (sex == Sex::male && waist_cm > neck_cm)
    return 86.010 * std::log10((waist_cm - neck_cm) * in) - 70.041 * std::log10(height_cm * in) +
           36.76;
  if (sex == Sex::female && waist_cm + hips_cm > neck_cm)
    return 163.205 * std::log10((waist_cm + hips_cm - neck_cm) * in) -
           97.684 * std::log10(height_cm * in) - 78.387;
  return std::numeric_limits<double>::quiet_NaN();
}

BodyMeasurements measure_body(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, Sex sex,
                              const MeasureOptions& o) {
  if (V.rows() == 0 || F.rows() == 0) throw InputError("measure: the mesh is empty");
  if (o.up_axis < 0 || o.up_axis > 2) throw InputError("measure: up axis must be 0, 1 or 2");
  if (!(std::isfinite(o.mm_per_unit) && o.mm_per_unit > 0))
    throw InputError("measure: mm_per_unit must be a finite number > 0, got " + std::to_string(o.mm_per_unit));
  if (!(std::isfinite(o.density_kg_per_l) && o.density_kg_per_l > 0))
    throw InputError("measure: density_kg_per_l must be a finite number > 0, got " + std::to_string(o.density_kg_per_l));
  if (!V.allFinite()) throw InputError("measure: the vertices contain NaN or infinite values");
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (F(f, k) < 0 || F(f, k) >= V.rows())
        throw InputError("measure: triangle " + std::to_string(f) + " has vertex index " + std::to_string(F(f, k)) +
                         ", the mesh has " + std::to_string(V.rows()) + " vertices");
  const double to_cm = o.mm_per_unit / 10.0;
  BodyMeasurements m;
  const double lo = V.col(o.up_axis).minCoeff(), hi = V.col(o.up_axis).maxCoeff();
  const double height = hi - lo;
  m.height_cm = height * to_cm;
  double vol = signed_volume(V, F);
  if (!(vol > 0))
    throw InputError("measure: the mesh encloses no positive volume (open, or faces point inward)");
  // An open surface encloses no definite volume: the divergence-theorem sum then depends on the
  // origin, moving by t·S/3 for a shift t, S = Σ of the triangles' area vectors (0 when closed).
  // A third of a body's faces removed still summed to 36.5 of its 54.9 L: refuse a surface whose
  // holes make the volume depend on the origin by more than 1 % over a shift of its own size.
  Eigen::RowVector3d area = Eigen::RowVector3d::Zero();
  for (Eigen::Index f = 0; f < F.rows(); ++f)
    area += 0.5 * (V.row(F(f, 1)) - V.row(F(f, 0))).cross(V.row(F(f, 2)) - V.row(F(f, 0)));
  const double size = (V.colwise().maxCoeff() - V.colwise().minCoeff()).norm();
  if (area.norm() * size / 3 > 0.01 * vol)
    throw InputError("measure: the surface is not closed (its holes make the volume uncertain by up to " +
                     std::to_string(static_cast<int>(std::ceil(100 * area.norm() * size / 3 / vol))) +
                     " %): volume, weight and girths need a watertight body");
  m.volume_l = vol * std::pow(o.mm_per_unit, 3) * 1e-6;
  m.weight_kg = m.volume_l * o.density_kg_per_l;

  // Vertical extent of every triangle, for listing each cut's candidate triangles.
  const int up = o.up_axis, n = o.slices_per_band;
  Eigen::VectorXd fmin(F.rows()), fmax(F.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const double a = V(F(f, 0), up), b = V(F(f, 1), up), c = V(F(f, 2), up);
    fmin(f) = std::min({a, b, c});
    fmax(f) = std::max({a, b, c});
  }

  // Cuts from the bottom of the band upwards. With `stop_at_jump`, the scan ends at the first
  // cut whose girth exceeds the previous one by more than 12 %: the arms joining the torso
  // loop at the armpits (A-pose), which must not count as chest.
  auto band = [&](double f0, double f1, bool maximum, double& at, bool stop_at_jump = false) {
    std::vector<double> fraction(n), h(n);
    for (int s = 0; s < n; ++s) {
      fraction[s] = f0 + (f1 - f0) * (s + 0.5) / n;
      h[s] = lo + fraction[s] * height;
    }
    // A plane section at height h only involves triangles whose extent contains h.
    std::vector<std::vector<int>> cut_faces(o.cut_band_triangles_only ? n : 0);
    if (o.cut_band_triangles_only && n > 0)
      for (Eigen::Index f = 0; f < F.rows(); ++f) {
        if (fmax(f) < h.front() || fmin(f) > h.back()) continue;
        const auto first = std::lower_bound(h.begin(), h.end(), fmin(f));
        const auto last = std::upper_bound(first, h.end(), fmax(f));
        for (auto it = first; it != last; ++it) cut_faces[it - h.begin()].push_back(static_cast<int>(f));
      }
    double best = maximum ? -1 : std::numeric_limits<double>::infinity();
    double previous = 0;
    Eigen::MatrixX3i Fc;
    for (int s = 0; s < n; ++s) {
      double g;
      if (o.cut_band_triangles_only) {
        Fc.resize(static_cast<Eigen::Index>(cut_faces[s].size()), 3);
        for (size_t k = 0; k < cut_faces[s].size(); ++k) Fc.row(static_cast<Eigen::Index>(k)) = F.row(cut_faces[s][k]);
        g = girth_at_height(V, Fc, h[s], up);
      } else {
        g = girth_at_height(V, F, h[s], up);
      }
      if (g <= 0) continue;
      if (stop_at_jump && previous > 0 && g > 1.12 * previous) break;
      previous = g;
      if (maximum ? g > best : g < best) { best = g; at = fraction[s] * height * to_cm; }
    }
    return std::isfinite(best) && best > 0 ? best * to_cm : 0.0;
  };
  if (o.band_girths) {
    m.neck_cm = band(0.80, 0.88, false, m.neck_at_cm);
    m.chest_cm = band(0.68, 0.80, true, m.chest_at_cm, true);
    m.waist_cm = band(0.55, 0.67, false, m.waist_at_cm);
    m.hips_cm = band(0.45, 0.55, true, m.hips_at_cm);
  } else {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    m.neck_cm = m.chest_cm = m.waist_cm = m.hips_cm = nan;
    m.neck_at_cm = m.chest_at_cm = m.waist_at_cm = m.hips_at_cm = nan;
  }
  if (o.survey_measurements && V.rows() == kSurveyTemplateVertexCount) measure_survey(V, F, o, lo, m);
  m.body_fat_pct = navy_body_fat_pct(sex, m.height_cm, m.neck_cm, m.waist_cm, m.hips_cm);
  return m;
}

}  // namespace bodymodel
