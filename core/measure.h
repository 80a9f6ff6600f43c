// Body measurements on a closed, outward-oriented triangle mesh in the standard (A-)pose.
//
// Definitions (docs/evaluation.md#body-measurements, docs/method.md §7):
//   height   extent along the up axis (+y for hm08 bodies).
//   volume   enclosed volume by the divergence theorem.
//   weight   volume × density; density 1.01 kg/L, a typical whole-body density with normal
//            residual lung volume (Siri 1961 and later densitometry put adults at 1.00–1.10).
//   girths   perimeter of the convex hull (CGAL convex_hull_2) of the torso's plane section:
//            the section is cut at many heights within a band (fractions of the height above
//            the lowest point) and the largest closed loop of each cut is the torso/neck loop:
//              neck   minimum over 0.80–0.88 h      chest  maximum over 0.68–0.80 h, below
//                                                   the armpits (first jump > 12 % ends it)
//              waist  minimum over 0.55–0.67 h      hips   maximum over 0.45–0.55 h
//   body fat U.S. Navy circumference method (Hodgdon & Beckett 1984), in inches:
//            men    86.010·log10(waist − neck) − 70.041·log10(height) + 36.76
//            women  163.205·log10(waist + hips − neck) − 97.684·log10(height) − 78.387
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>

namespace bodymodel {

struct MeasureOptions {
  int up_axis = 1;                  // 0 = x, 1 = y (hm08), 2 = z
  double density_kg_per_l = 1.01;   // see header comment
  double mm_per_unit = 1.0;         // mesh unit in millimetres (bodies here are in mm)
  int slices_per_band = 40;         // cuts per girth band
  // Each cut looks only at the triangles whose vertical extent contains its height (listed once
  // per band) instead of at every triangle: the same sections, about 4x faster on a 27k-triangle
  // body. `false` cuts the whole mesh every time (the reference the tests compare against).
  bool cut_band_triangles_only = true;
};

enum class Sex { unknown, female, male };

struct BodyMeasurements {
  double height_cm = 0;
  double volume_l = 0;
  double weight_kg = 0;
  double neck_cm = 0, chest_cm = 0, waist_cm = 0, hips_cm = 0;
  // Heights (cm above the lowest point) at which each girth was found.
  double neck_at_cm = 0, chest_at_cm = 0, waist_at_cm = 0, hips_at_cm = 0;
  double body_fat_pct = 0;          // NaN when the sex is unknown
};

// V #V by 3, F #F by 3 (closed, outward-oriented). Throws InputError for an empty mesh or a
// non-positive volume (open or inward-facing surface).
BodyMeasurements measure_body(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                              Sex sex = Sex::unknown, const MeasureOptions& options = {});

// Girth at height `h` (mesh units, along the up axis): perimeter of the convex hull of the
// largest closed loop of the plane section, in mesh units; 0 when the plane misses the mesh.
double girth_at_height(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F, double h,
                       int up_axis = 1);

// U.S. Navy body-fat estimate (%), arguments in centimetres.
double navy_body_fat_pct(Sex sex, double height_cm, double neck_cm, double waist_cm,
                         double hips_cm);

}  // namespace bodymodel
