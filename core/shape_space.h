// A shape space learned from real bodies: a linear (PCA) space over MakeHuman's body parameters —
// the macro sliders, the measurement modifiers and the body-shape modifiers — fitted to real
// people (e.g. ANSUR II's soldiers, population/shape_space_fit.h). The registration's shape fit
// (registration/shape_fit.h) moves a template inside it, with the people's variances as its
// prior, instead of inside MakeHuman's six macro sliders, whose proportions are MakeHuman's guess.
//
// A parameter vector is p = mean + basis·(sd ∘ c): c in standard deviations of the people, so the
// Gaussian prior is ½‖c‖². A space learned from both sexes keeps them apart: p = mean +
// g·sex_direction + basis·(sd ∘ c), mean the women's mean, sex_direction the men's mean minus it,
// g ∈ [0, 1] (the gender slider) and the components learned within each sex — a pooled PCA would
// couple gender with breasts and belly and let a man's fit slide into an in-between body with
// both. The body of p is MakeHuman's build with the macros clamped to their range (weight up to
// 1.25, as the proportion fit extrapolates it) and the modifiers to ±1.5.
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
  Eigen::VectorXd sex_direction;  // per parameter: men's mean − women's (empty: one population)
  double explained = 0;      // fraction of the people's variance the components keep
  int people = 0;            // bodies it was learned from
  std::string source;        // what they were (free text, e.g. the files)

  int components() const { return static_cast<int>(sd.size()); }
  bool has_sex() const { return sex_direction.size() > 0; }
  // Coefficients of a body: the components' (sd units), then g when has_sex().
  int dimension() const { return components() + (has_sex() ? 1 : 0); }
  // InputError naming `what` when the sizes disagree, a value is not finite, an sd is not
  // positive, or a parameter is unknown to `makehuman`.
  void validate(const MakeHuman& makehuman, const std::string& what) const;
};

// The MakeHuman parameters of coefficients c (dimension() values; empty = the mean, g = 0.5).
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

// A space of body shapes over the template's 13 380 body vertices, V(c) = mean + Σ_k c_k·offsets_k
// (+ Σ_k ½c_k²·curvature_k when given: second order along each component, no cross terms), c in
// the people's standard deviations (Gaussian prior ½‖c‖²). It is how a model the project built
// (`bodymodel build`) serves as the registration's shape space: its PCA shape space linearised
// around the mean body (model/model_shape_space.h). Its bodies are not MakeHuman builds: the
// skeleton is placed from the vertices as MakeHuman's joints are (MakeHuman::skeleton_from_body)
// and the weights are the template's.
struct VertexShapeSpace {
  Eigen::MatrixX3d mean;    // 13380 by 3, mm, MakeHuman's rest pose and frame (+y up)
  Eigen::MatrixXd offsets;  // 3·13380 by K: column k = (x, y, z of vertex 0, vertex 1, …) of +1 sd
  Eigen::MatrixXd curvature;  // empty, or as offsets: the second derivative along each component
  std::string source;       // what it was made from (free text, e.g. the model file)
  int components() const { return static_cast<int>(offsets.cols()); }
  // InputError naming `what` when the sizes are not the body template's or a value is not finite.
  void validate(const std::string& what) const;
};
// The body of coefficients c (components() values; empty = the mean body): vertices, the skeleton
// placed from them (MakeHuman::skeleton_from_body), the template's weights; mm.
MakeHuman::Body vertex_space_body(const MakeHuman& makehuman, const VertexShapeSpace& space,
                                  const Eigen::VectorXd& c);
// Its vertices alone (13380 by 3, mm).
Eigen::MatrixX3d vertex_space_body_vertices(const VertexShapeSpace& space, const Eigen::VectorXd& c);

// The parameter names of a MakeHuman with its modifiers loaded, in the order above: the macros
// gender, age, muscle, weight, height, proportions, cup, firmness, then the measurement and the
// body-shape modifiers.
std::vector<std::string> shape_space_parameter_names(const MakeHuman& makehuman);

// PCA of the rows of X (people by parameters, named `parameters`): the first `components`
// principal directions (fewer when the rows span fewer). With `male` (1/0 per row, both present)
// the sexes' means are kept apart (sex_direction) and the components learned within each sex.
// InputError for fewer than 2 rows or a width that disagrees with the names.
ShapeSpace learn_shape_space(const std::vector<std::string>& parameters, const Eigen::MatrixXd& X,
                             int components, const std::string& source, const std::vector<int>& male = {});

}  // namespace bodymodel
