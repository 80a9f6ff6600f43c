// A shape space learned from real bodies: a linear (PCA) space over MakeHuman's body parameters —
// the macro sliders, the measurement modifiers and the body-shape modifiers — fitted to real
// people (e.g. ANSUR II's soldiers, population/shape_space_fit.h). The registration's shape fit
// (registration/shape_fit.h) moves a template inside it, with the people's variances as its
// prior, instead of inside MakeHuman's six macro sliders, whose proportions are MakeHuman's guess.
//
// A parameter vector is p = mean + basis·(sd ∘ c): c in standard deviations of the people, so the
// Gaussian prior is ½‖c‖². The body of p is MakeHuman's build with the macros clamped to their
// range (weight up to 1.25, as the proportion fit extrapolates it) and the modifiers to ±1.5.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/makehuman.h"

namespace bodymodel {

// Macro slider names: "gender", "age", "muscle", "weight", "height", "proportions", "cup",
// "firmness", and the ethnic weights "african", "asian", "caucasian" (set with
// MacroSettings::set_ethnic, so the three keep summing to 1). InputError for another name.
double macro_slider(const MacroSettings& s, const std::string& name);
void set_macro_slider(MacroSettings* s, const std::string& name, double value);

struct ShapeSpace {
  // One per parameter: "macro/<slider>" (macro_slider names), "measure/<name>"
  // (MakeHuman::measure_modifier_names()), "shape/<name>" (MakeHuman::shape_modifiers()).
  std::vector<std::string> parameters;
  Eigen::VectorXd mean;      // per parameter
  Eigen::MatrixXd basis;     // parameters by components, orthonormal columns
  Eigen::VectorXd sd;        // per component: the people's standard deviation along it
  double explained = 0;      // fraction of the people's variance the components keep
  int people = 0;            // bodies it was learned from
  std::string source;        // what they were (free text, e.g. the files)

  int components() const { return static_cast<int>(sd.size()); }
  // InputError naming `what` when the sizes disagree, a value is not finite, an sd is not
  // positive, or a parameter is unknown to `makehuman`.
  void validate(const MakeHuman& makehuman, const std::string& what) const;
};

// The MakeHuman parameters of coefficients c (components() values, in sd units; empty = the mean).
struct ShapeParameters {
  MacroSettings macros;
  Eigen::VectorXd measure;   // per MakeHuman::measure_modifier_names()
  Eigen::VectorXd shape;     // per MakeHuman::shape_modifiers()
};
ShapeParameters shape_space_parameters(const MakeHuman& makehuman, const ShapeSpace& space,
                                       const Eigen::VectorXd& c);
// The body of coefficients c (13 380-vertex body, its skeleton and weights; mm).
MakeHuman::Body shape_space_body(const MakeHuman& makehuman, const ShapeSpace& space,
                                 const Eigen::VectorXd& c);

// The parameter names of a MakeHuman with its modifiers loaded, in the order above: the macros
// gender, age, muscle, weight, height, proportions, cup, firmness, then the measurement and the
// body-shape modifiers.
std::vector<std::string> shape_space_parameter_names(const MakeHuman& makehuman);

// PCA of the rows of X (people by parameters, named `parameters`): the first `components`
// principal directions (fewer when the rows span fewer). InputError for fewer than 2 rows or a
// width that disagrees with the names.
ShapeSpace learn_shape_space(const std::vector<std::string>& parameters, const Eigen::MatrixXd& X,
                             int components, const std::string& source);

}  // namespace bodymodel
