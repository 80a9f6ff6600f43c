// bodymodel.Model: the PCA body model with semantic labels (model/): load, labels and components
// as arrays, morph by labels, generate bodies, measure.
#include <fmt/format.h>

#include <mutex>

#include "core/body_size.h"
#include "core/error.h"
#include "model/body_model.h"
#include "model/fit.h"
#include "model/fit_labels.h"
#include "model/generate_crowd.h"
#include "model/model_file.h"
#include "model/morph.h"
#include "model/morph_request.h"
#include "python/common.h"

namespace bodymodel::py {

namespace {

using namespace pybind11::literals;

double label_value(const std::string& label, const pyb::handle& v) {
  if (label == "sex" && pyb::isinstance<pyb::str>(v)) {
    const std::string s = pyb::str(v);
    if (s == "female" || s == "f") return 0;
    if (s == "male" || s == "m") return 1;
    throw InputError("sex: expected 'female', 'male', 0 or 1, got '" + s + "'");
  }
  double x;
  try {
    x = v.cast<double>();
  } catch (const pyb::cast_error&) {
    throw InputError(fmt::format("value of '{}': expected a number, got {}", label, std::string(pyb::repr(v))));
  }
  if (!std::isfinite(x)) throw InputError(fmt::format("value of '{}': '{}' is not a number", label, x));
  return x;
}

// A condition from a Python value: a number (exact), a (lo, hi) pair (range) or "keep".
LabelCondition condition(const SemanticRegression& reg, const std::string& label, const pyb::handle& v) {
  reg.index(label);  // InputError listing the valid names
  if (pyb::isinstance<pyb::str>(v) && std::string(pyb::str(v)) == "keep") return LabelCondition::keep_current(label);
  if (pyb::isinstance<pyb::tuple>(v) || pyb::isinstance<pyb::list>(v)) {
    auto seq = v.cast<pyb::sequence>();
    if (seq.size() != 2) throw InputError(fmt::format("{}: a range is (lo, hi), got {} values", label, seq.size()));
    const double lo = label_value(label, seq[0]), hi = label_value(label, seq[1]);
    if (!(lo < hi)) throw InputError(fmt::format("--where {}: empty range {}..{}", label, lo, hi));
    return LabelCondition::range(label, lo, hi);
  }
  return LabelCondition::exact(label, label_value(label, v));
}

pyb::dict summary_dict(const MorphSummary& s) {
  pyb::dict d;
  d["iterations"] = s.iterations;
  d["converged"] = s.converged;
  d["change_norm"] = s.change_norm;
  d["seconds"] = s.seconds;
  d["decodes"] = s.decodes;
  pyb::list labels;
  for (const auto& l : s.labels)
    labels.append(pyb::dict("label"_a = l.label, "target"_a = l.target, "lo"_a = l.lo, "hi"_a = l.hi,
                            "start"_a = l.start, "achieved"_a = l.achieved, "measured"_a = l.measured,
                            "satisfied"_a = l.satisfied));
  d["labels"] = labels;
  d["report"] = s.report();
  return d;
}

class PyModel {
 public:
  explicit PyModel(std::shared_ptr<const BodyModel> m) : model_(std::move(m)) {}
  // A pointer: the object holds a mutex (not movable).
  static std::unique_ptr<PyModel> load(const std::string& path) {
    std::shared_ptr<const BodyModel> m;
    {
      pyb::gil_scoped_release nogil;
      m = std::make_shared<const BodyModel>(load_model(path));
    }
    return std::make_unique<PyModel>(std::move(m));
  }
  const BodyModel& model() const { return *model_; }
  // The morpher (and its decoder's factorisations) is built on first use and reused.
  const ShapeMorpher& morpher() const {
    std::lock_guard lock(mutex_);
    if (!morpher_) morpher_ = std::make_unique<ShapeMorpher>(model_);
    return *morpher_;
  }

  pyb::tuple morph(const pyb::handle& V, const std::string& sex, int iterations, const pyb::handle& mask,
                   bool closest, const std::string& change, const pyb::kwargs& labels) const {
    const SemanticRegression& reg = model_->shape.regression;
    if (labels.empty()) throw InputError("morph: nothing to do: give at least one LABEL=VALUE");
    std::vector<LabelCondition> cond;
    for (auto [k, v] : labels) cond.push_back(condition(reg, pyb::str(k), v));
    if (sex != "female" && sex != "male" && sex != "unknown")
      throw InputError("sex: expected 'female', 'male' or 'unknown', got '" + sex + "'");
    // As `bodymodel morph` (model/morph_request.h): the likely change from the mean body.
    MorphOptions o = morph_request_options(cond, sex == "female" ? Sex::female : sex == "male" ? Sex::male : Sex::unknown,
                                           change, V.is_none(), iterations);
    if (!mask.is_none()) {
      o.triangle_mask = vector(mask, "mask");
      if (o.triangle_mask.size() != model_->tmpl->triangle_count())
        throw InputError(fmt::format("mask: {} values, expected one per triangle ({})", o.triangle_mask.size(),
                                     model_->tmpl->triangle_count()));
    }
    // As `bodymodel morph` (model/morph.h's morph_body: the same morph and fold repair), from V or
    // from the model's mean body (template-aligned).
    Eigen::MatrixX3d X;
    if (!V.is_none()) {
      X = vertices(V, "V");
      model_->tmpl->check_vertices(X, "V");
      check_body_size(X, "V");
    }
    MorphedBody morphed;
    {
      const ShapeMorpher& mo = morpher();
      pyb::gil_scoped_release nogil;
      morphed = morph_body(mo, V.is_none() ? nullptr : &X, cond, o);
    }
    const MorphSummary& sum = morphed.summary;
    const Eigen::MatrixX3d& out = morphed.V;
    // A target the model cannot meet is an error unless the closest body is asked for.
    if (!sum.converged && !closest) {
      const std::string missed = unmet_labels(sum);
      throw InputError(fmt::format("morph: the model cannot meet {} from '{}' after {} iterations (closest=True returns "
                                   "the closest body)", missed, V.is_none() ? "the mean body" : "V", sum.iterations));
    }
    pyb::dict d = summary_dict(sum);
    d["folds_repaired"] = morphed.folds.flipped_before - morphed.folds.flipped_after;
    return pyb::make_tuple(to_array(Eigen::MatrixXd(out)), d);
  }

  // As `bodymodel fit` (tools/verbs/fit.cc) on a mesh whose vertices are V: the same checks
  // and messages (with "V" for the file name), the same fitter and options, the same labels.
  pyb::tuple fit(const pyb::handle& V, int components, bool pose, int iterations, double prior, double scale,
                 const std::string& sex, const pyb::object& progress) const {
    if (components == 0 || components < -1)
      throw InputError(fmt::format("--components must be ≥ 1 or -1, got {}", components));
    if (scale < 0 || !std::isfinite(scale)) throw InputError("--scale must be positive (or 0: the model's)");
    if (iterations < 0) throw InputError("--iterations must be ≥ 0");
    if (sex != "female" && sex != "male" && sex != "unknown")
      throw InputError("sex: expected 'female', 'male' or 'unknown', got '" + sex + "'");
    const BodyModel& bm = *model_;
    const bool full = pose || bm.metadata.value("shape_model", "") == "full";
    const SubModel& sub = full ? bm.full : bm.shape;
    if (components > sub.component_count())
      throw InputError(fmt::format("--components {}: the {} model has {} components", components,
                                   full ? "full" : "shape", sub.component_count()));
    const double scale_given = scale;
    if (scale == 0) {
      scale = 1;
      if (bm.metadata.contains("source") && bm.metadata["source"].contains("mm_per_unit"))
        scale = bm.metadata["source"]["mm_per_unit"].get<double>();
    }
    const Eigen::MatrixX3d Y = vertices(V, "V") * scale;
    const Eigen::MatrixX3i F = bm.tmpl->faces();
    bm.check_topology(Y, F, "V");
    check_body_size(Y, "V", "--scale", scale, scale_given == 0);
    ModelFitOptions o;
    o.components = components;
    o.max_iterations = iterations;
    o.prior_weight = prior;
    ProgressCallback cb = progress_callback(progress);
    ModelFit r;
    std::vector<FitLabel> labels;
    {
      pyb::gil_scoped_release nogil;
      // A fitter per call: its set-up is small next to the fit, and calls may run concurrently.
      ModelFitter fitter(bm.tmpl, bm.mean, sub.pca);
      r = fitter.fit(Y, o, cb);
      labels = fit_labels(bm, sub, r.coefficients, Y, r.V, F,
                          sex == "female" ? Sex::female : sex == "male" ? Sex::male : Sex::unknown);
    }
    const ModelFitSummary& s = r.summary;
    pyb::dict d;
    d["sub_model"] = full ? "full" : "shape";
    d["components"] = s.components;
    d["coefficients"] = to_array(r.coefficients);
    d["input_mm_per_unit"] = scale;
    d["vertex_error_mm"] = pyb::dict("mean"_a = s.mean_mm, "rms"_a = s.rms_mm, "p95"_a = s.p95_mm, "max"_a = s.max_mm);
    d["vertex_error"] = to_array(r.vertex_error);
    d["start_mean_vertex_error_mm"] = s.start_mean_mm;
    d["iterations"] = s.iterations;
    d["jacobians"] = s.jacobians;
    d["decodes"] = s.evaluations;
    d["converged"] = s.converged;
    d["stop_reason"] = s.stop_reason;
    d["history_mean_vertex_error_mm"] = s.history_mean_mm;
    d["seconds"] = s.seconds;
    pyb::dict lab;
    for (const FitLabel& l : labels) {
      pyb::dict j;
      j["unit"] = l.unit;
      if (l.predicted) j["predicted"] = *l.predicted;
      if (l.measured_input) j["measured_input"] = *l.measured_input;
      if (l.measured_fitted) j["measured_fitted"] = *l.measured_fitted;
      lab[pyb::str(l.name)] = j;
    }
    d["labels"] = lab;
    d["report"] = s.report();
    return pyb::make_tuple(to_array(Eigen::MatrixXd(r.V)), d);
  }

  pyb::list generate(int n, uint64_t seed, const pyb::handle& where, double spread, bool measure_girths,
                     const pyb::object& progress) const {
    if (n < 0) throw InputError("generate: n must be >= 0");
    const SemanticRegression& reg = model_->shape.regression;
    std::vector<LabelCondition> cond;
    if (!where.is_none())
      for (auto [k, v] : where.cast<pyb::dict>()) cond.push_back(condition(reg, pyb::str(k), v));
    GenerateCrowdOptions o;
    o.seed = seed;
    o.generate.spread = spread;
    o.generate.measure_girths = measure_girths;
    std::vector<int> idx(n);
    for (int i = 0; i < n; ++i) idx[i] = i;
    std::vector<CrowdBody> bodies(n);
    ProgressCallback cb = progress_callback(progress);
    {
      pyb::gil_scoped_release nogil;
      generate_crowd_bodies(model_, cond, idx, o, [&](CrowdBody&& b) { bodies[b.index] = std::move(b); }, cb);
    }
    pyb::list out;
    for (auto& b : bodies) {
      pyb::dict d;
      d["V"] = to_array(Eigen::MatrixXd(b.body.V));
      d["encoding"] = to_array(b.body.encoding);
      pyb::dict meas;
      const auto& m = b.body.measured;
      meas["height_cm"] = m.height_cm, meas["volume_l"] = m.volume_l, meas["weight_kg"] = m.weight_kg;
      meas["neck_cm"] = m.neck_cm, meas["chest_cm"] = m.chest_cm, meas["waist_cm"] = m.waist_cm;
      meas["hips_cm"] = m.hips_cm, meas["body_fat_pct"] = m.body_fat_pct;
      d["measured"] = meas;
      d["satisfied"] = b.body.satisfied;
      d["attempts"] = b.body.attempts;
      d["flipped_triangles"] = b.flipped_triangles;
      d["summary"] = summary_dict(b.body.summary);
      out.append(d);
    }
    return out;
  }

 private:
  std::shared_ptr<const BodyModel> model_;
  mutable std::mutex mutex_;
  mutable std::unique_ptr<ShapeMorpher> morpher_;
};

pyb::list label_names(const SubModel& s) {
  pyb::list l;
  for (const auto& i : s.regression.labels) l.append(i.name);
  return l;
}

}  // namespace

void bind_model(pyb::module_& m) {
  pyb::class_<PyModel>(m, "Model", R"(A PCA body model with semantic labels (`bodymodel build` writes it).

Model.load(path) reads the .npz. The shape model (one standard-pose body per subject) is what
morph() and generate() use. Encodings are 15 values per triangle relative to encoding_mean.)")
      .def_static("load", &PyModel::load, "path"_a,
                  "Model.load(path) -> Model: reads a model .npz; InputError naming the file and key when it is not one.")
      .def_property_readonly("template_vertices", [](const PyModel& p) { return to_array(Eigen::MatrixXd(p.model().tmpl->rest_vertices())); },
                             "(n, 3) float64, mm: the template's rest shape (mean of the standard-pose scans).")
      .def_property_readonly("faces", [](const PyModel& p) { return to_array(Eigen::MatrixXi(p.model().tmpl->faces())); },
                             "(m, 3) int32: the model's triangles.")
      .def_property_readonly("encoding_mean", [](const PyModel& p) { return to_array(p.model().mean->values); },
                             "(15·m,) absolute encoding mean of all scans.")
      .def_property_readonly("label_names", [](const PyModel& p) { return label_names(p.model().shape); },
                             "The shape model's L label names (height_cm, weight_kg, sex, ...).")
      .def_property_readonly("label_units", [](const PyModel& p) {
            pyb::list l;
            for (const auto& i : p.model().shape.regression.labels) l.append(i.unit);
            return l;
          }, "Units of the labels, in label_names' order.")
      .def_property_readonly("labels", [](const PyModel& p) { return to_array(p.model().shape.labels); },
                             "(N, L) float64: the training subjects' label values (NaN = unknown).")
      .def_property_readonly("subject_ids", [](const PyModel& p) { return p.model().shape.sample_ids; })
      .def_property_readonly("components", [](const PyModel& p) { return to_array(p.model().shape.pca.basis); },
                             "(15·m, K) float64: the shape model's orthonormal PCA basis (columns).")
      .def_property_readonly("eigenvalues", [](const PyModel& p) { return to_array(p.model().shape.pca.eigenvalues); },
                             "(K,) variance of each shape coefficient, descending.")
      .def_property_readonly("shape_mean", [](const PyModel& p) { return to_array(p.model().shape.pca.mean); },
                             "(15·m,) encoding of the shape model's mean (relative to encoding_mean).")
      .def_property_readonly("coefficients", [](const PyModel& p) { return to_array(p.model().shape.pca.coefficients); },
                             "(N, K) shape coefficients of the training subjects.")
      .def_property_readonly("label_gradients", [](const PyModel& p) { return to_array(p.model().shape.regression.gradients); },
                             "(K, L) eq. 10 gradients s: the morph direction of each label (label unit per coefficient).")
      .def_property_readonly("label_offsets", [](const PyModel& p) { return to_array(p.model().shape.regression.offsets); },
                             "(L,) eq. 10 offsets o: label ≈ o + c @ s.")
      .def("encode", [](const PyModel& p, const pyb::handle& V) {
             Eigen::MatrixX3d X = vertices(V, "V");
             pyb::gil_scoped_release nogil;
             Eigen::VectorXd x = p.model().encode(X, "V").values;
             pyb::gil_scoped_acquire gil;
             return to_array(x);
           }, "V"_a, "encode(V) -> (15·m,): encoding of a body V (n, 3), mm, relative to encoding_mean.")
      .def("decode", [](const PyModel& p, const pyb::handle& x) {
             Eigen::VectorXd e = vector(x, "encoding");
             if (e.size() != p.model().tmpl->encoding_size())
               throw InputError(fmt::format("encoding: {} values, the model needs {}", e.size(), p.model().tmpl->encoding_size()));
             const ShapeMorpher& mo = p.morpher();
             pyb::gil_scoped_release nogil;
             Eigen::MatrixX3d V = mo.decode(e);
             pyb::gil_scoped_acquire gil;
             return to_array(Eigen::MatrixXd(V));
           }, "encoding"_a, "decode(encoding) -> V (n, 3) mm: decodes values relative to encoding_mean, template-aligned.")
      .def("predict_labels", [](const PyModel& p, const pyb::handle& V) {
             Eigen::MatrixX3d X = vertices(V, "V");
             const BodyModel& bm = p.model();
             bm.tmpl->check_vertices(X, "V");
             check_body_size(X, "V");
             Eigen::VectorXd c = bm.shape.pca.project(bm.encode(X, "V").values);
             return to_array(Eigen::VectorXd(bm.shape.regression.predict(c)));
           }, "V"_a, "predict_labels(V) -> (L,): the eq. 10 regression's labels of body V (label_names' order).")
      .def("morph", &PyModel::morph, "V"_a = pyb::none(), pyb::kw_only(), "sex"_a = "unknown", "iterations"_a = 8,
           "mask"_a = pyb::none(), "closest"_a = false, "change"_a = "",
           R"(morph(V=None, *, sex='unknown', iterations=8, mask=None, closest=False, change='', **labels) -> (V', summary)

Changes body V ((n, 3), mm, the model's topology; None = the model's mean body) to meet the
label values given as keywords, as `bodymodel morph`: height_cm=185 (exact), weight_kg='keep'
(hold the current value), waist_cm=(80, 90) (a range); sex accepts 'female'/'male'. Measurable
labels (height, weight, girths) are met as measured on the output (a few corrected decodes).
mask: (m,) per-triangle weights in [0, 1] restricting the change. Returns the morphed vertices
(n, 3), rigidly placed onto V, and a summary dict (iterations, converged, decodes, labels: per
label target/start/achieved/satisfied, report: the CLI's table). A target the model cannot meet
raises InputError, as the CLI fails, unless closest=True (the CLI's --closest). change: 'likely'
(the model's conditional mean; the default from the mean body) or 'smallest' (eq. 11; the default
from V), the CLI's --change.)")
      .def("fit", &PyModel::fit, "V"_a, pyb::kw_only(), "components"_a = -1, "pose"_a = false, "iterations"_a = 20,
           "prior"_a = 0.0, "scale"_a = 0.0, "sex"_a = "unknown", "progress"_a = pyb::none(),
           R"(fit(V, *, components=-1, pose=False, iterations=20, prior=0.0, scale=0.0, sex='unknown', progress=None) -> (V', summary)

Fits the model to a body V ((n, 3), the model's vertex order, e.g. a registered scan), as
`bodymodel fit`: the first `components` coefficients (-1: all) and a rigid placement minimising
the vertex error of the decoded body, by Levenberg-Marquardt through the decoder (docs/model.md).
pose=True fits the full (pose and shape) model instead of the shape model. scale: millimetres
per unit of V (0: the unit the model was built from). prior: weight (mm²) of a Gaussian prior on
the coefficients. Returns the fitted vertices (n, 3), mm, placed on V, and a summary dict with
the keys of the CLI's JSON: coefficients (K,), vertex_error_mm {mean, rms, p95, max},
vertex_error (n,) mm, iterations, converged, stop_reason, labels {name: {unit, predicted, measured_input,
measured_fitted}}, ... Runs with the GIL released; progress(fraction, what) per iteration.)")
      .def("generate", &PyModel::generate, "n"_a, "seed"_a = 1, pyb::kw_only(), "where"_a = pyb::none(),
           "spread"_a = 1.0, "measure_girths"_a = true, "progress"_a = pyb::none(),
           R"(generate(n, seed=1, *, where=None, spread=1.0, measure_girths=True, progress=None) -> list

n random bodies from the shape model, as `bodymodel generate --count n --seed seed`: body k is
the same for any n. where: {label: value | (lo, hi)} conditions met as measured, e.g.
{'sex': 'female', 'weight_kg': 65, 'height_cm': (160, 180)}. Each body is a dict: V (n, 3) mm,
encoding, measured (height_cm, weight_kg, ...), satisfied, attempts, flipped_triangles,
summary. Runs in parallel with the GIL released; progress(fraction, what) per body.)");
}

}  // namespace bodymodel::py
