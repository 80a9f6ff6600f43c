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
//   survey   on bodies with the hm08 template's topology (13 380 vertices, e.g. MakeHuman bodies,
//            registered meshes, model outputs), the NHANES definitions (README of the NHANES
//            data; landmarks in core/landmarks.h survey_landmarks(), right side as NHANES):
//              waist_iliac_cm        horizontal girth at the height of the right iliac crest
//              hips_cm               horizontal girth at the level of the maximum posterior
//                                    extension of the buttocks, searched in the lower half of
//                                    the crotch → iliac crest span (on other meshes: the band
//                                    above)
//              arm_circumference_cm  girth of the right upper arm in the plane perpendicular to
//                                    the acromion→olecranon line through its midpoint
//              upper_arm_length_cm   straight distance acromion → olecranon
//              upper_leg_length_cm   straight distance inguinal crease → top of the patella
//            Girths are convex-hull perimeters (a tape bridges hollows) as above. NHANES takes
//            both lengths seated with the joint bent 90° along the skin; here they are straight
//            lines on the standing A-pose mesh, so they are systematically shorter than the
//            survey's (docs/population.md gives the measured offsets).
//   body fat U.S. Navy circumference method (Hodgdon & Beckett 1984), in inches:
//            men    86.010·log10(waist − neck) − 70.041·log10(height) + 36.76
//            women  163.205·log10(waist + hips − neck) − 97.684·log10(height) − 78.387
#pragma once

#include <Eigen/Core>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace bodymodel {

struct MeasureOptions {
  int up_axis = 1;                  // 0 = x, 1 = y (hm08), 2 = z
  double density_kg_per_l = 1.01;   // see header comment
  double mm_per_unit = 1.0;         // mesh unit in millimetres (bodies here are in mm)
  int slices_per_band = 40;         // cuts per girth band
  // Each cut looks only at the triangles whose vertical extent contains its height (listed once
  // per band) instead of at every triangle: the same sections, several times faster
  // (docs/benchmarks.md#figures-behind-code-comments). `false` cuts the whole mesh every time (the reference the tests compare against).
  bool cut_band_triangles_only = true;
  // Neck, chest, natural waist and the band hip (and so body fat); false = NaN, several times faster
  // (fit-measurements' inner loop, which needs only height, weight and the survey measures).
  bool band_girths = true;
  // The survey measurements (header comment) on template-topology bodies; false = NaN.
  bool survey_measurements = true;
  // The hip is searched from 1 cm above the crotch up to this fraction of the way to the iliac
  // crest: the buttocks lie in the lower half; above them the lower back and the flanks of
  // MakeHuman's heavy bodies stick out further back than the buttocks, and a search up to the
  // crest puts such a body's "hip" 2 cm under its waist (measured: heavy male, 0.55 of the
  // height against the crest's 0.57), where the hip and waist modifiers cannot tell them apart.
  double hip_band_fraction = 0.5;
  int hip_slices = 30;              // cuts in that band (about 3 mm apart)
  // Levels whose posterior extension is within this of the largest count as "the maximum
  // extension of the buttocks" (a flat seat); the largest girth among them is the hip.
  double hip_extension_tolerance_mm = 2.0;
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
  // Survey measurements (header comment): NaN unless the mesh has the hm08 body topology.
  double waist_iliac_cm = std::numeric_limits<double>::quiet_NaN();
  double arm_circumference_cm = std::numeric_limits<double>::quiet_NaN();
  double upper_arm_length_cm = std::numeric_limits<double>::quiet_NaN();
  double upper_leg_length_cm = std::numeric_limits<double>::quiet_NaN();
  double waist_iliac_at_cm = std::numeric_limits<double>::quiet_NaN();  // cm above the lowest point
  bool survey = false;              // whether the survey definitions were applied
};

// Number of body vertices of the hm08 template (MakeHuman's group "body"): meshes with this many
// vertices get the survey measurements.
inline constexpr int kSurveyTemplateVertexCount = 13380;

// The measurement names `bodymodel measure --json`, fit-measurements and the morph labels use,
// with their unit and one-line definition (for --help and the docs).
struct MeasurementDefinition {
  const char* name;
  const char* unit;
  const char* definition;
};
const std::vector<MeasurementDefinition>& measurement_definitions();
// The value of a named measurement (measurement_definitions() names), NaN when not available.
double measurement_value(const BodyMeasurements& m, const std::string& name);

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
