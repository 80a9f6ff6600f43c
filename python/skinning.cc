// Skinning (skinning/) on numpy arrays: rig fits from example frames, a Rig with deform(), the
// error metrics.
#include <fmt/format.h>

#include <chrono>

#include "core/error.h"
#include "python/common.h"
#include "skinning/method_comparison.h"
#include "skinning/rig_io.h"
#include "skinning/sequence_evaluation.h"
#include "skinning/skinning_error.h"
#include "skinning/skinning_model.h"
#include "skinning/skinning_rig.h"

namespace bodymodel::py {

namespace {

using namespace pybind11::literals;

struct PyRig {
  SkinningRig rig;
  Eigen::MatrixX3i faces;  // may be empty
};

Eigen::MatrixX3d deform(const PyRig& r, const pyb::handle& M_in) {
  BoneTransforms M = bone_transforms(M_in, "bone_transforms");
  if (static_cast<int>(M.size()) != r.rig.bone_count)
    throw InputError(fmt::format("bone_transforms: {} bones, the rig has {}", M.size(), r.rig.bone_count));
  pyb::gil_scoped_release nogil;
  return evaluate_rig(r.rig, M);
}

// Example poses: a (P, n, 3) array or a sequence of (n, 3) arrays.
std::vector<Eigen::MatrixX3d> frames(const pyb::handle& h, const std::string& what) {
  std::vector<Eigen::MatrixX3d> out;
  pyb::array a = pyb::array::ensure(h);
  if (a && a.ndim() == 3) {
    for (pyb::ssize_t p = 0; p < a.shape(0); ++p)
      out.push_back(vertices(a[pyb::int_(p)], fmt::format("{}[{}]", what, p)));
  } else {
    PyErr_Clear();
    if (!pyb::isinstance<pyb::sequence>(h)) throw InputError(what + ": expected (P, n, 3) or a list of (n, 3) arrays");
    auto seq = h.cast<pyb::sequence>();
    for (size_t p = 0; p < seq.size(); ++p) out.push_back(vertices(seq[p], fmt::format("{}[{}]", what, p)));
  }
  return out;
}

std::vector<BoneTransforms> pose_transforms(const pyb::handle& h, const std::string& what) {
  std::vector<BoneTransforms> out;
  pyb::array a = pyb::array::ensure(h);
  if (a && a.ndim() == 4) {
    for (pyb::ssize_t p = 0; p < a.shape(0); ++p)
      out.push_back(bone_transforms(a[pyb::int_(p)], fmt::format("{}[{}]", what, p)));
  } else {
    PyErr_Clear();
    if (!pyb::isinstance<pyb::sequence>(h)) throw InputError(what + ": expected (P, B, 3, 4) bone maps");
    auto seq = h.cast<pyb::sequence>();
    for (size_t p = 0; p < seq.size(); ++p) out.push_back(bone_transforms(seq[p], fmt::format("{}[{}]", what, p)));
  }
  return out;
}

pyb::tuple fit_rig(const pyb::handle& rest_in, const pyb::handle& poses_in, const pyb::handle& transforms_in,
                   const std::string& method_name, int max_influences, double as_ridge, double mwe_s,
                   int mwe_components, const pyb::object& progress) {
  const SkinningModel method = parse_skinning_model(method_name);
  if (method != SkinningModel::ssd && method != SkinningModel::dqs && method != SkinningModel::as &&
      method != SkinningModel::mwe)
    throw InputError("fit_rig: method '" + method_name + "' is a pose-space rig; the module fits ssd, dqs, as and mwe");
  PreparedSequence prep;
  SkinningExamples& ex = prep.examples;
  ex.rest = vertices(rest_in, "rest");
  ex.poses = frames(poses_in, "poses");
  ex.transforms = pose_transforms(transforms_in, "transforms");
  for (size_t p = 0; p < ex.poses.size(); ++p)
    if (ex.poses[p].rows() != ex.rest.rows())
      throw InputError(fmt::format("poses[{}]: {} vertices, the rest mesh has {}", p, ex.poses[p].rows(), ex.rest.rows()));
  if (ex.transforms.size() != ex.poses.size())
    throw InputError(fmt::format("transforms: {} poses of bone maps for {} example poses", ex.transforms.size(), ex.poses.size()));
  for (size_t p = 1; p < ex.transforms.size(); ++p)
    if (ex.transforms[p].size() != ex.transforms[0].size())
      throw InputError(fmt::format("transforms[{}]: {} bones, the first pose {}", p, ex.transforms[p].size(), ex.transforms[0].size()));
  if (static_cast<int>(ex.poses.size()) < minimum_examples(method))
    throw InputError(fmt::format("{} needs at least {} example poses, got {}", skinning_model_name(method),
                                 minimum_examples(method), ex.poses.size()));
  // The settings of `bodymodel skin fit --transforms ... --cv none` (tools/verbs/skin_fit.cc).
  SequenceEvaluationOptions opt;
  opt.max_influences = max_influences;
  opt.cv.scheme = CvScheme::none;
  opt.fit.animation_space.ridge = as_ridge;
  opt.fit.mwe.ridge_scale = mwe_s;
  opt.fit.mwe.components = mwe_components;
  ProgressCallback cb = progress_callback(progress);
  MethodFit mf;
  FittedModel fitted;
  {
    pyb::gil_scoped_release nogil;
    LbsFitOptions lo = opt.lbs;
    lo.max_influences = max_influences;
    prep.lbs = fit_lbs(ex, {}, lo, &prep.lbs_summary, [&](double f, std::string_view w) { return !cb || cb(0.3 * f, w); });
    fitted = fit_sequence_method(method, prep, opt, nullptr, &mf,
                                 [&](double f, std::string_view w) { return !cb || cb(0.3 + 0.7 * f, w); });
  }
  PyRig r{fitted.rig, {}};
  pyb::dict summary;
  summary["ssd"] = prep.lbs_summary.brief();
  summary["fit"] = mf.brief;
  summary["seconds"] = mf.seconds;
  summary["rms_residual"] = prep.lbs_summary.rms_residual;
  return pyb::make_tuple(std::move(r), summary);
}

}  // namespace

void bind_skinning(pyb::module_& m) {
  pyb::class_<PyRig>(m, "Rig", R"(A linear skinning rig (ssd, dqs, as or mwe; skinning/skinning_rig.h).

Rig.load(path) reads a rig .npz (`bodymodel skin fit` writes them); fit_rig() fits one. Bone
maps are (B, 3, 4) arrays [R t] (or (B, 4, 4)) taking rest positions to posed ones.)")
      .def_static("load", [](const std::string& path) {
            PyRig r;
            r.rig = load_rig(path, &r.faces);
            return r;
          }, "path"_a, "Rig.load(path) -> Rig; InputError naming the file and key when it is not a linear rig.")
      .def("save", [](const PyRig& r, const std::string& path, const pyb::handle& F) {
            Eigen::MatrixX3i Fi = F.is_none() ? r.faces : faces(F, "F", r.rig.vertex_count());
            save_rig(path, r.rig, Fi);
          }, "path"_a, "F"_a = pyb::none(), "save(path, F=None): writes the rig .npz (F (m, 3) triangles for viewers).")
      .def("deform", [](const PyRig& r, const pyb::handle& M) {
            // No copy: the array takes over the evaluated matrix (column-major, so the array is
            // Fortran-ordered); deform is called per frame and a copy cost as much as MWE's work.
            auto* V = new Eigen::MatrixX3d(deform(r, M));
            pyb::capsule owner(V, [](void* p) { delete static_cast<Eigen::MatrixX3d*>(p); });
            const pyb::ssize_t n = V->rows();
            return pyb::array_t<double>({n, pyb::ssize_t(3)},
                                        {pyb::ssize_t(sizeof(double)), pyb::ssize_t(sizeof(double)) * n}, V->data(),
                                        owner);
          },
           "bone_transforms"_a,
           R"(deform(bone_transforms) -> V (n, 3)

Posed vertices for B bone maps (B, 3, 4) (or (B, 4, 4)): the reference double-precision
evaluation (skinning/skinning_rig.h evaluate_rig), in the rig's unit. Releases the GIL. The
array is Fortran-ordered (it is the evaluator's own matrix, not a copy).)")
      .def("time_native", [](const PyRig& r, const pyb::handle& M_in, int repeats) {
            BoneTransforms M = bone_transforms(M_in, "bone_transforms");
            if (static_cast<int>(M.size()) != r.rig.bone_count) throw InputError("bone_transforms: wrong bone count");
            pyb::gil_scoped_release nogil;
            auto t0 = std::chrono::steady_clock::now();
            double sink = 0;
            for (int i = 0; i < repeats; ++i) sink += evaluate_rig(r.rig, M)(0, 0);
            const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
            return sink == sink ? s / std::max(1, repeats) : s;
          }, "bone_transforms"_a, "repeats"_a = 10,
           "time_native(bone_transforms, repeats=10) -> seconds per frame of the same evaluation looped in C++ (the benchmark's baseline).")
      .def_property_readonly("method", [](const PyRig& r) { return skinning_method_name(r.rig.method); })
      .def_property_readonly("bone_count", [](const PyRig& r) { return r.rig.bone_count; })
      .def_property_readonly("rest", [](const PyRig& r) { return to_array(Eigen::MatrixXd(r.rig.rest)); }, "(n, 3) rest positions.")
      .def_property_readonly("faces", [](const PyRig& r) { return to_array(Eigen::MatrixXi(r.faces)); }, "(m, 3) triangles (0 rows when unknown).")
      .def_property_readonly("influences", [](const PyRig& r) { return to_array(r.rig.influences); },
                             "(n, K) int32 bone per influence slot, -1 = unused.")
      .def_property_readonly("coefficients", [](const PyRig& r) { return to_array(r.rig.coefficients); },
                             "(n, K·c) float64: c = 1 (ssd, dqs), 4 (as) or 12 (mwe) per slot (layout in skinning/rig_io.h).");

  m.def("fit_rig", &fit_rig, "rest"_a, "poses"_a, "transforms"_a, "method"_a = "mwe", pyb::kw_only(),
        "max_influences"_a = 4, "as_ridge"_a = AnimationSpaceFitOptions{}.ridge,
        "mwe_s"_a = MweFitOptions{}.ridge_scale, "mwe_components"_a = MweFitOptions{}.components,
        "progress"_a = pyb::none(),
        R"(fit_rig(rest, poses, transforms, method='mwe', *, max_influences=4, as_ridge, mwe_s, mwe_components, progress=None) -> (Rig, summary)

Fits a rig to example frames with known bone maps, as `bodymodel skin fit --transforms ...
--cv none`: SSD weights (non-negative, sum one, influences chosen automatically), then
Animation Space (ridge as_ridge) or MWE (relative ridge scale mwe_s) over them.
rest (n, 3); poses (P, n, 3) or a list of (n, 3); transforms (P, B, 3, 4). method: ssd, dqs,
as, mwe. summary: the fits' one-line reports. Releases the GIL; progress(fraction, what).)");

  m.def("mesh_deviation", [](const pyb::handle& X, const pyb::handle& Y, const pyb::handle& F) {
          Eigen::MatrixX3d Xm = vertices(X, "X"), Ym = vertices(Y, "Y");
          if (Xm.rows() != Ym.rows()) throw InputError(fmt::format("X has {} vertices, Y {}", Xm.rows(), Ym.rows()));
          Eigen::MatrixX3i Fi = faces(F, "F", Ym.rows());
          MeshDeviation d;
          {
            pyb::gil_scoped_release nogil;
            d = mesh_deviation(Xm, Ym, Fi);
          }
          return pyb::dict("geometric"_a = to_array(d.geometric), "normal_deg"_a = to_array(d.normal_deg),
                           "vertex"_a = to_array(d.vertex));
        }, "X"_a, "Y"_a, "F"_a,
        R"(mesh_deviation(X, Y, F) -> dict of (n,) arrays

Per-vertex errors of a result X (n, 3) against a reference Y (n, 3) with triangles F (m, 3)
(docs/evaluation.md): geometric = distance to the reference surface (data units), normal_deg =
angle between vertex normals (degrees), vertex = |x_i - y_i|.)");
  m.def("e_rms", [](const pyb::handle& X, const pyb::handle& Y) {
          auto Xs = frames(X, "X"), Ys = frames(Y, "Y");
          if (Xs.size() != Ys.size() || Xs.empty()) throw InputError("e_rms: X and Y need the same, non-zero number of frames");
          double sq = 0;
          long long n = 0;
          Eigen::Vector3d lo = Ys[0].colwise().minCoeff(), hi = Ys[0].colwise().maxCoeff();
          for (size_t f = 0; f < Xs.size(); ++f) {
            if (Xs[f].rows() != Ys[f].rows()) throw InputError(fmt::format("e_rms: frame {} has {} and {} vertices", f, Xs[f].rows(), Ys[f].rows()));
            sq += (Xs[f] - Ys[f]).squaredNorm();
            n += Xs[f].rows();
            lo = lo.cwiseMin(Ys[f].colwise().minCoeff().transpose());
            hi = hi.cwiseMax(Ys[f].colwise().maxCoeff().transpose());
          }
          return 1000.0 * std::sqrt(sq) / (std::sqrt(3.0 * n) * (hi - lo).norm());
        }, "X"_a, "Y"_a,
        "e_rms(X, Y) -> float: Kavan et al.'s E_RMS = 1000·|X - Y|_F / (sqrt(3·n·f)·d), frames (f, n, 3), d the diagonal of the reference frames' bounding box.");

  m.def("compare_skinning", [](const pyb::handle& frames_in, const pyb::handle& F_in, const std::vector<std::string>& methods,
                               const std::vector<int>& train, bool leave_one_out, int rest, int bones,
                               const std::string& cv, unsigned seed, const pyb::object& progress) {
          const std::vector<Eigen::MatrixX3d> fr = frames(frames_in, "frames");
          if (fr.empty()) throw InputError("frames: none given");
          const Eigen::MatrixX3i Fm = faces(F_in, "faces", fr[0].rows());
          SequenceEvaluationOptions o;
          o.methods.clear();
          for (const auto& m : methods) o.methods.push_back(parse_skinning_model(m));
          if (o.methods.empty()) throw InputError("methods: none given");
          if (bones < 1) throw InputError(fmt::format("bones must be at least 1, got {}", bones));
          o.recovery.bones = bones;
          o.recovery.seed = seed;
          FrameSplitRequest r;
          r.leave_one_out = leave_one_out;
          r.train = train;
          r.rest = rest;
          const FrameSplit split = split_frames(int(fr.size()), r);
          o.cv = parse_cv_scheme(cv, split.forecast);
          const ProgressCallback cb = progress_callback(progress);
          SkinningComparison c;
          {
            pyb::gil_scoped_release nogil;
            c = compare_skinning_methods(fr, Fm, split, o, cb);
          }
          pyb::dict out;
          for (size_t m = 0; m < c.methods.size(); ++m) {
            pyb::dict row;
            for (int s = 0; s < 2; ++s) {
              const DeviationStats& st = s == 0 ? c.train[m] : c.unseen[m];
              row[s == 0 ? "train" : "unseen"] =
                  pyb::dict("mean_geometric"_a = st.mean_geometric(), "max_geometric"_a = st.max_geometric,
                            "mean_normal_deg"_a = st.mean_normal_deg(), "e_rms"_a = st.e_rms(c.last.diagonal),
                            "frames"_a = st.frames);
            }
            row["frame_error"] = c.frame_error[m];
            row["fit_cpu_s"] = c.fit_cpu[m];
            out[pyb::str(skinning_model_name(c.methods[m]))] = row;
          }
          return pyb::make_tuple(out, pyb::dict("protocol"_a = split.protocol, "rest"_a = split.rest,
                                                "frame_split"_a = c.frame_split, "cv"_a = cv_description(o.cv)));
        }, "frames"_a, "faces"_a, pyb::kw_only(), "methods"_a = std::vector<std::string>{"ssd", "as", "mwe"},
        "train"_a = std::vector<int>{}, "leave_one_out"_a = false, "rest"_a = -1, "bones"_a = 24, "cv"_a = "auto",
        "seed"_a = 1u, "progress"_a = pyb::none(),
        R"(compare_skinning(frames, faces, *, methods=['ssd', 'as', 'mwe'], train=[], leave_one_out=False, rest=-1, bones=24, cv='auto', seed=1, progress=None) -> (per_method, protocol)

`bodymodel skin eval`'s comparison (docs/skinning.md) on frames (f, n, 3) sharing faces (m, 3):
bones recovered from the training frames (train: frame indices; empty: 10 evenly spaced, at least
one unseen; leave_one_out: every frame but the rest one held out in turn), every method fitted
with its regularisation cross-validated on the training frames (cv: auto, none, folds:K,
last:N). per_method: {method: {train: {...}, unseen: {mean_geometric, max_geometric,
mean_normal_deg, e_rms, frames}, frame_error (f,), fit_cpu_s}}; protocol: the split's
description, rest frame, each frame's split and the cross-validation scheme. Releases the GIL.)");
}

}  // namespace bodymodel::py
