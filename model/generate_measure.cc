#include "model/generate_measure.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "core/geometry.h"

namespace bodymodel {

BodyMeasurements measure_body_banded(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, Sex sex,
                                     const MeasureOptions& o) {
  if (V.rows() == 0 || F.rows() == 0) throw InputError("measure: the mesh is empty");
  if (o.up_axis < 0 || o.up_axis > 2) throw InputError("measure: up axis must be 0, 1 or 2");
  const int up = o.up_axis;
  const double to_cm = o.mm_per_unit / 10.0;
  BodyMeasurements m;
  const double lo = V.col(up).minCoeff(), hi = V.col(up).maxCoeff();
  const double height = hi - lo;
  m.height_cm = height * to_cm;
  const double vol = signed_volume(V, F);
  if (!(vol > 0))
    throw InputError("measure: the mesh encloses no positive volume (open, or faces point inward)");
  m.volume_l = vol * std::pow(o.mm_per_unit, 3) * 1e-6;
  m.weight_kg = m.volume_l * o.density_kg_per_l;

  // Vertical extent of every triangle (once); per band and cut, the triangles whose extent
  // contains the cut's height (a superset of the ones the plane crosses).
  Eigen::VectorXd fmin(F.rows()), fmax(F.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const double a = V(F(f, 0), up), b = V(F(f, 1), up), c = V(F(f, 2), up);
    fmin(f) = std::min({a, b, c});
    fmax(f) = std::max({a, b, c});
  }
  const int n = o.slices_per_band;
  // The band scan of measure_body (core/measure.cc), each cut on its own triangles.
  auto band = [&](double f0, double f1, bool maximum, double& at, bool stop_at_jump = false) {
    std::vector<double> fraction(n), h(n);
    for (int s = 0; s < n; ++s) {
      fraction[s] = f0 + (f1 - f0) * (s + 0.5) / n;
      h[s] = lo + fraction[s] * height;
    }
    std::vector<std::vector<int>> cut_faces(n);
    if (n > 0)
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
      Fc.resize(static_cast<Eigen::Index>(cut_faces[s].size()), 3);
      for (size_t k = 0; k < cut_faces[s].size(); ++k) Fc.row(k) = F.row(cut_faces[s][k]);
      double g = girth_at_height(V, Fc, h[s], up);
      if (g <= 0) continue;
      if (stop_at_jump && previous > 0 && g > 1.12 * previous) break;
      previous = g;
      if (maximum ? g > best : g < best) {
        best = g;
        at = fraction[s] * height * to_cm;
      }
    }
    return std::isfinite(best) && best > 0 ? best * to_cm : 0.0;
  };
  m.neck_cm = band(0.80, 0.88, false, m.neck_at_cm);
  m.chest_cm = band(0.68, 0.80, true, m.chest_at_cm, true);
  m.waist_cm = band(0.55, 0.67, false, m.waist_at_cm);
  m.hips_cm = band(0.45, 0.55, true, m.hips_at_cm);
  m.body_fat_pct = navy_body_fat_pct(sex, m.height_cm, m.neck_cm, m.waist_cm, m.hips_cm);
  return m;
}

}  // namespace bodymodel
