#include "model/generate_measure.h"

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

  // Vertical extent of every triangle (once), then per band the triangles overlapping it.
  Eigen::VectorXd fmin(F.rows()), fmax(F.rows());
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const double a = V(F(f, 0), up), b = V(F(f, 1), up), c = V(F(f, 2), up);
    fmin(f) = std::min({a, b, c});
    fmax(f) = std::max({a, b, c});
  }
  auto band_faces = [&](double h0, double h1) {
    std::vector<int> keep;
    for (Eigen::Index f = 0; f < F.rows(); ++f)
      if (fmax(f) >= h0 && fmin(f) <= h1) keep.push_back(static_cast<int>(f));
    Eigen::MatrixX3i Fb(keep.size(), 3);
    for (size_t k = 0; k < keep.size(); ++k) Fb.row(k) = F.row(keep[k]);
    return Fb;
  };
  // The band scan of measure_body (core/measure.cc), on the band's triangles.
  auto band = [&](double f0, double f1, bool maximum, double& at, bool stop_at_jump = false) {
    const Eigen::MatrixX3i Fb = band_faces(lo + f0 * height, lo + f1 * height);
    double best = maximum ? -1 : std::numeric_limits<double>::infinity();
    double previous = 0;
    for (int s = 0; s < o.slices_per_band; ++s) {
      double f = f0 + (f1 - f0) * (s + 0.5) / o.slices_per_band;
      double g = girth_at_height(V, Fb, lo + f * height, up);
      if (g <= 0) continue;
      if (stop_at_jump && previous > 0 && g > 1.12 * previous) break;
      previous = g;
      if (maximum ? g > best : g < best) {
        best = g;
        at = f * height * to_cm;
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
