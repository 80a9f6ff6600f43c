#include "core/shape_space.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace bodymodel {

double macro_slider(const MacroSettings& s, const std::string& n) {
  if (n == "gender") return s.gender;
  if (n == "age") return s.age;
  if (n == "muscle") return s.muscle;
  if (n == "weight") return s.weight;
  if (n == "height") return s.height;
  if (n == "proportions") return s.proportions;
  if (n == "cup") return s.cup;
  if (n == "firmness") return s.firmness;
  if (n == "african") return s.african;
  if (n == "asian") return s.asian;
  if (n == "caucasian") return s.caucasian;
  throw InputError("unknown macro slider '" + n +
                   "' (expected gender, age, muscle, weight, height, proportions, cup, firmness, "
                   "african, asian, caucasian)");
}

void set_macro_slider(MacroSettings* s, const std::string& n, double v) {
  if (!std::isfinite(v)) throw InputError("macro slider '" + n + "': value is not finite");
  v = std::clamp(v, 0.0, 1.0);
  if (n == "gender") s->gender = v;
  else if (n == "age") s->age = v;
  else if (n == "muscle") s->muscle = v;
  else if (n == "weight") s->weight = v;
  else if (n == "height") s->height = v;
  else if (n == "proportions") s->proportions = v;
  else if (n == "cup") s->cup = v;
  else if (n == "firmness") s->firmness = v;
  else if (n == "african" || n == "asian" || n == "caucasian") s->set_ethnic(n, v);
  else macro_slider(*s, n);  // throws the unknown-name error
}

namespace {

const std::vector<std::string>& space_macros() {
  static const std::vector<std::string> m = {"gender", "age",         "muscle", "weight",
                                             "height", "proportions", "cup",    "firmness"};
  return m;
}

// Where a parameter goes: kind 0 macro, 1 measure modifier, 2 shape modifier; index within it.
struct Slot {
  int kind = -1, index = -1;
};

Slot slot_of(const MakeHuman& mh, const std::string& p) {
  const auto starts = [&](const char* pre) { return p.rfind(pre, 0) == 0; };
  if (starts("macro/")) {
    const auto& m = space_macros();
    const auto it = std::find(m.begin(), m.end(), p.substr(6));
    return it == m.end() ? Slot{} : Slot{0, int(it - m.begin())};
  }
  if (starts("measure/")) {
    const int k = mh.measure_modifier_index(p.substr(8));
    return k < 0 ? Slot{} : Slot{1, k};
  }
  if (starts("shape/")) {
    const int k = mh.shape_modifier_index(p.substr(6));
    return k < 0 ? Slot{} : Slot{2, k};
  }
  return {};
}

}  // namespace

std::vector<std::string> shape_space_parameter_names(const MakeHuman& mh) {
  std::vector<std::string> names;
  for (const auto& m : space_macros()) names.push_back("macro/" + m);
  for (const auto& m : mh.measure_modifier_names()) names.push_back("measure/" + m);
  for (const auto& m : mh.shape_modifiers()) names.push_back("shape/" + m.name);
  return names;
}

void ShapeSpace::validate(const MakeHuman& mh, const std::string& what) const {
  const int P = static_cast<int>(parameters.size());
  if (P == 0 || mean.size() != P || basis.rows() != P || basis.cols() != sd.size() || sd.size() == 0 ||
      (has_sex() && sex_direction.size() != P))
    throw InputError(what + ": shape space sizes disagree (" + std::to_string(P) + " parameters, mean " +
                     std::to_string(mean.size()) + ", basis " + std::to_string(basis.rows()) + " by " +
                     std::to_string(basis.cols()) + ", " + std::to_string(sd.size()) + " sd)");
  if (!mean.allFinite() || !basis.allFinite() || !sd.allFinite() || !sex_direction.allFinite() ||
      (sd.array() <= 0).any())
    throw InputError(what + ": shape space has a non-finite value or an sd that is not positive");
  for (const auto& p : parameters)
    if (slot_of(mh, p).kind < 0)
      throw InputError(what + ": unknown shape-space parameter '" + p +
                       "' (expected macro/<slider>, measure/<modifier> or shape/<modifier> of this MakeHuman data)");
}

ShapeParameters shape_space_parameters(const MakeHuman& mh, const ShapeSpace& s, const Eigen::VectorXd& c) {
  Eigen::VectorXd p = s.mean;
  if (c.size() > 0 && c.size() != s.dimension())
    throw InputError("shape space: " + std::to_string(c.size()) + " coefficients for " +
                     std::to_string(s.components()) + " components" + (s.has_sex() ? " and the sex" : ""));
  if (c.size() > 0) p += s.basis * s.sd.cwiseProduct(c.head(s.components()));
  if (s.has_sex()) p += std::clamp(c.size() > 0 ? c[s.components()] : 0.5, 0.0, 1.0) * s.sex_direction;
  ShapeParameters out;
  out.measure = Eigen::VectorXd::Zero(mh.measure_modifier_names().size());
  out.shape = Eigen::VectorXd::Zero(mh.shape_modifiers().size());
  // Clamped to the range the proportion fit uses (weight extrapolated to 1.25, modifiers ±1.5):
  // a coefficient far out must still give a body.
  constexpr double kModifierLimit = 1.5;
  for (size_t k = 0; k < s.parameters.size(); ++k) {
    const Slot sl = slot_of(mh, s.parameters[k]);
    const double v = p[k];
    if (sl.kind == 0) {
      const std::string& m = space_macros()[sl.index];
      if (m == "weight") out.macros.weight = std::clamp(v, 0.0, 1.25);
      else set_macro_slider(&out.macros, m, v);
    } else if (sl.kind == 1) {
      out.measure[sl.index] = std::clamp(v, -kModifierLimit, kModifierLimit);
    } else if (sl.kind == 2) {
      const bool two = mh.shape_modifiers()[sl.index].two_sided;
      out.shape[sl.index] = std::clamp(v, two ? -kModifierLimit : 0.0, kModifierLimit);
    }
  }
  return out;
}

MakeHuman::Body shape_space_body(const MakeHuman& mh, const ShapeSpace& s, const Eigen::VectorXd& c) {
  const ShapeParameters p = shape_space_parameters(mh, s, c);
  MakeHuman::BuildOptions o;
  o.allow_extrapolation = true;
  return mh.body(p.macros, p.measure, p.shape, o);
}

void VertexShapeSpace::validate(const std::string& what) const {
  const int nv = MakeHuman::kBodyVertexCount;
  if (mean.rows() != nv || offsets.rows() != 3 * nv)
    throw InputError(what + ": a vertex shape space needs " + std::to_string(nv) + " body vertices (MakeHuman's "
                     "topology), found " + std::to_string(mean.rows()) + " (offsets " + std::to_string(offsets.rows()) +
                     " rows)");
  if (curvature.size() > 0 && (curvature.rows() != offsets.rows() || curvature.cols() != offsets.cols()))
    throw InputError(what + ": the vertex shape space's curvature is not the size of its offsets");
  if (!mean.allFinite() || !offsets.allFinite() || !curvature.allFinite()) throw InputError(what + ": a vertex shape space value is not finite");
}

Eigen::MatrixX3d vertex_space_body_vertices(const VertexShapeSpace& s, const Eigen::VectorXd& c) {
  if (c.size() != 0 && c.size() != s.components())
    throw InputError("vertex shape space: " + std::to_string(c.size()) + " coefficients for " +
                     std::to_string(s.components()) + " components");
  Eigen::MatrixX3d V = s.mean;
  if (c.size() > 0) {
    Eigen::VectorXd d = s.offsets * c;  // x, y, z per vertex
    if (s.curvature.size() > 0) d += s.curvature * (0.5 * c.array().square()).matrix();
    V += Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(d.data(), s.mean.rows(), 3);
  }
  return V;
}

MakeHuman::Body vertex_space_body(const MakeHuman& mh, const VertexShapeSpace& s, const Eigen::VectorXd& c) {
  MakeHuman::Body b;
  b.mesh.V = vertex_space_body_vertices(s, c);
  b.mesh.F = mh.body_faces();
  b.skeleton = mh.skeleton_from_body(b.mesh.V);
  b.weights = mh.body_weights();
  return b;
}

ShapeSpace learn_shape_space(const std::vector<std::string>& parameters, const Eigen::MatrixXd& X, int components,
                             const std::string& source, const std::vector<int>& male) {
  if (X.rows() < 2) throw InputError("shape space: needs at least 2 bodies, found " + std::to_string(X.rows()));
  if (X.cols() != static_cast<Eigen::Index>(parameters.size()))
    throw InputError("shape space: " + std::to_string(X.cols()) + " values per body for " +
                     std::to_string(parameters.size()) + " parameter names");
  if (!X.allFinite()) throw InputError("shape space: a body's parameters are not finite");
  ShapeSpace s;
  s.parameters = parameters;
  s.people = static_cast<int>(X.rows());
  s.source = source;
  if (!male.empty() && male.size() != size_t(X.rows()))
    throw InputError("shape space: " + std::to_string(male.size()) + " sex labels for " + std::to_string(X.rows()) + " bodies");
  const int men = static_cast<int>(std::count(male.begin(), male.end(), 1));
  const bool two = !male.empty() && men > 0 && men < static_cast<int>(male.size());
  Eigen::MatrixXd D(X.rows(), X.cols());
  if (two) {
    Eigen::VectorXd m[2] = {Eigen::VectorXd::Zero(X.cols()), Eigen::VectorXd::Zero(X.cols())};
    for (Eigen::Index i = 0; i < X.rows(); ++i) m[male[i] == 1] += X.row(i).transpose();
    m[0] /= double(X.rows() - men);
    m[1] /= double(men);
    s.mean = m[0];
    s.sex_direction = m[1] - m[0];
    for (Eigen::Index i = 0; i < X.rows(); ++i) D.row(i) = X.row(i) - m[male[i] == 1].transpose();
  } else {
    s.mean = X.colwise().mean().transpose();
    D = X.rowwise() - s.mean.transpose();
  }
  const Eigen::MatrixXd C = D.transpose() * D / double(X.rows() - (two ? 2 : 1));
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(C);
  const Eigen::VectorXd lambda = eig.eigenvalues().reverse();  // descending
  const double total = std::max(lambda.sum(), 1e-300);
  // Directions with (numerically) no variance are dropped: they would have sd 0.
  int K = 0;
  while (K < std::min<int>(components, int(lambda.size())) && lambda[K] > 1e-10 * total) ++K;
  if (K == 0) throw InputError("shape space: the bodies do not vary");
  s.basis = eig.eigenvectors().rowwise().reverse().leftCols(K);
  s.sd = lambda.head(K).cwiseSqrt();
  s.explained = lambda.head(K).sum() / total;
  return s;
}

}  // namespace bodymodel
