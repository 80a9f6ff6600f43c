// The Python module `bodymodel`: meshes, MakeHuman bodies, measurements and the relative rotation
// encoding here; the model (model.cc), skinning and regression (skinning.cc) in their own files.
// Every call takes numpy arrays and returns numpy arrays; long calls release the GIL.
#include <fmt/format.h>

#include <cmath>

#include "core/data_path.h"
#include "core/error.h"
#include "core/io/mesh_io.h"
#include "core/makehuman.h"
#include "core/measure.h"
#include "core/survey_columns.h"
#include "encoding/relative_rotation_decoder.h"
#include "encoding/relative_rotation_encoding.h"
#include "python/common.h"

namespace bodymodel::py {

namespace {

std::string shape_text(const pyb::array& a) {
  std::string s = "(";
  for (pyb::ssize_t i = 0; i < a.ndim(); ++i) s += (i ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

DoubleArray as_doubles(const pyb::handle& h, const std::string& what) {
  auto a = DoubleArray::ensure(h);
  if (!a) {
    PyErr_Clear();
    throw InputError(fmt::format("{}: expected a numeric array, got {}", what,
                                 std::string(pyb::str(h.get_type().attr("__name__")))));
  }
  return a;
}

void check_finite(const double* p, pyb::ssize_t n, pyb::ssize_t cols, const std::string& what) {
  for (pyb::ssize_t k = 0; k < n; ++k)
    if (!std::isfinite(p[k]))
      throw InputError(fmt::format("{}: {} at row {}, column {}", what, std::isnan(p[k]) ? "NaN" : "infinity",
                                   k / cols, k % cols));
}

}  // namespace

Eigen::MatrixX3d vertices(const pyb::handle& h, const std::string& what, bool allow_empty) {
  DoubleArray a = as_doubles(h, what);
  if (a.ndim() != 2 || a.shape(1) != 3 || (!allow_empty && a.shape(0) == 0))
    throw InputError(fmt::format("{}: expected an (n, 3) array of positions, got shape {}", what, shape_text(a)));
  check_finite(a.data(), a.size(), 3, what);
  Eigen::MatrixX3d V(a.shape(0), 3);
  auto r = a.unchecked<2>();
  for (pyb::ssize_t i = 0; i < a.shape(0); ++i)
    for (int c = 0; c < 3; ++c) V(i, c) = r(i, c);
  return V;
}

Eigen::MatrixX3i faces(const pyb::handle& h, const std::string& what, long vertex_count) {
  pyb::array raw = pyb::array::ensure(h);
  if (!raw) {
    PyErr_Clear();
    throw InputError(fmt::format("{}: expected an integer (m, 3) array", what));
  }
  const char kind = raw.dtype().kind();
  if (kind != 'i' && kind != 'u')
    throw InputError(fmt::format("{}: expected integer vertex indices, got dtype {} (indices are not rounded)",
                                 what, std::string(pyb::str(raw.dtype()))));
  auto a = pyb::array_t<int64_t, pyb::array::c_style | pyb::array::forcecast>::ensure(raw);
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw InputError(fmt::format("{}: expected an (m, 3) array of triangles, got shape {}", what, shape_text(a)));
  Eigen::MatrixX3i F(a.shape(0), 3);
  auto r = a.unchecked<2>();
  for (pyb::ssize_t i = 0; i < a.shape(0); ++i)
    for (int c = 0; c < 3; ++c) {
      const int64_t v = r(i, c);
      if (v < 0 || (vertex_count >= 0 && v >= vertex_count) || v > INT32_MAX)
        throw InputError(fmt::format("{}: triangle {} has vertex index {}, expected 0..{}", what, i, v,
                                     vertex_count >= 0 ? vertex_count - 1 : INT32_MAX));
      F(i, c) = static_cast<int>(v);
    }
  return F;
}

Eigen::MatrixXd matrix(const pyb::handle& h, const std::string& what, bool allow_nan) {
  DoubleArray a = as_doubles(h, what);
  if (a.ndim() != 2) throw InputError(fmt::format("{}: expected a 2-D array, got shape {}", what, shape_text(a)));
  if (!allow_nan) check_finite(a.data(), a.size(), std::max<pyb::ssize_t>(1, a.shape(1)), what);
  Eigen::MatrixXd M(a.shape(0), a.shape(1));
  auto r = a.unchecked<2>();
  for (pyb::ssize_t i = 0; i < a.shape(0); ++i)
    for (pyb::ssize_t c = 0; c < a.shape(1); ++c) M(i, c) = r(i, c);
  return M;
}

Eigen::VectorXd vector(const pyb::handle& h, const std::string& what, bool allow_nan) {
  DoubleArray a = as_doubles(h, what);
  if (a.ndim() != 1) throw InputError(fmt::format("{}: expected a 1-D array, got shape {}", what, shape_text(a)));
  if (!allow_nan) check_finite(a.data(), a.size(), 1, what);
  return Eigen::Map<const Eigen::VectorXd>(a.data(), a.shape(0));
}

BoneTransforms bone_transforms(const pyb::handle& h, const std::string& what) {
  DoubleArray a = as_doubles(h, what);
  if (a.ndim() != 3 || a.shape(1) < 3 || a.shape(1) > 4 || a.shape(2) != 4)
    throw InputError(fmt::format("{}: expected (B, 3, 4) or (B, 4, 4) bone maps, got shape {}", what, shape_text(a)));
  check_finite(a.data(), a.size(), a.shape(1) * 4, what);
  auto r = a.unchecked<3>();
  BoneTransforms M(a.shape(0));
  for (pyb::ssize_t b = 0; b < a.shape(0); ++b) {
    M[b].setIdentity();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 4; ++j) M[b].matrix()(i, j) = r(b, i, j);
  }
  return M;
}

pyb::array_t<double> bone_transforms_array(const BoneTransforms& M) {
  pyb::array_t<double> out({static_cast<pyb::ssize_t>(M.size()), pyb::ssize_t(3), pyb::ssize_t(4)});
  auto w = out.mutable_unchecked<3>();
  for (size_t b = 0; b < M.size(); ++b)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 4; ++j) w(b, i, j) = M[b].matrix()(i, j);
  return out;
}

pyb::array_t<double> to_array(const Eigen::MatrixXd& M) {
  pyb::array_t<double> out({static_cast<pyb::ssize_t>(M.rows()), static_cast<pyb::ssize_t>(M.cols())});
  auto w = out.mutable_unchecked<2>();
  for (Eigen::Index i = 0; i < M.rows(); ++i)
    for (Eigen::Index c = 0; c < M.cols(); ++c) w(i, c) = M(i, c);
  return out;
}

pyb::array_t<double> to_array(const Eigen::VectorXd& v) {
  pyb::array_t<double> out(static_cast<pyb::ssize_t>(v.size()));
  std::copy(v.data(), v.data() + v.size(), out.mutable_data());
  return out;
}

pyb::array_t<int32_t> to_array(const Eigen::MatrixXi& M) {
  pyb::array_t<int32_t> out({static_cast<pyb::ssize_t>(M.rows()), static_cast<pyb::ssize_t>(M.cols())});
  auto w = out.mutable_unchecked<2>();
  for (Eigen::Index i = 0; i < M.rows(); ++i)
    for (Eigen::Index c = 0; c < M.cols(); ++c) w(i, c) = M(i, c);
  return out;
}

ProgressCallback progress_callback(const pyb::object& cb) {
  if (cb.is_none()) return {};
  if (!PyCallable_Check(cb.ptr())) throw InputError("progress: expected a callable progress(fraction, what)");
  // Held through a shared_ptr whose deleter takes the GIL: the library copies and destroys the
  // std::function on threads that do not hold it.
  auto holder = std::shared_ptr<pyb::object>(new pyb::object(cb), [](pyb::object* o) {
    pyb::gil_scoped_acquire gil;
    delete o;
  });
  return [holder](double fraction, std::string_view what) -> bool {
    pyb::gil_scoped_acquire gil;
    if (PyErr_CheckSignals() != 0) throw pyb::error_already_set();
    pyb::object r = (*holder)(fraction, std::string(what));
    return r.is_none() || r.cast<bool>();
  };
}

namespace {

Sex parse_sex(const std::string& s) {
  if (s == "female" || s == "f") return Sex::female;
  if (s == "male" || s == "m") return Sex::male;
  if (s == "unknown" || s.empty()) return Sex::unknown;
  throw InputError("sex: expected 'female', 'male' or 'unknown', got '" + s + "'");
}

// The MakeHuman data, loaded once per process (≈ 0.3 s) on first use.
const MakeHuman& makehuman(const std::string& dir) {
  static std::mutex mutex;
  static std::map<std::string, MakeHuman> loaded;
  std::lock_guard lock(mutex);
  auto it = loaded.find(dir);
  if (it == loaded.end())
    it = loaded.emplace(dir, dir.empty() ? MakeHuman::load() : MakeHuman::load(dir)).first;
  return it->second;
}

// The ANSUR II measurer of the default MakeHuman data, built once per process.
const AnsurMeasurer& ansur_measurer() {
  static const AnsurMeasurer measurer = [] {
    const MakeHuman& mh = makehuman("");
    const MakeHuman::Body ref = mh.body(MacroSettings{});
    return AnsurMeasurer(mh.body_faces(), mh.body_weights(), ref.mesh.V, ref.skeleton);
  }();
  return measurer;
}

struct PyTemplate {
  std::shared_ptr<const EncodingTemplate> tmpl;
};

std::shared_ptr<const EncodingTemplate> make_template(const pyb::handle& rest_V, const pyb::handle& F) {
  Eigen::MatrixX3d V = vertices(rest_V, "rest_V");
  Eigen::MatrixX3i Fi = faces(F, "F", V.rows());
  return std::make_shared<const EncodingTemplate>(std::move(V), std::move(Fi));
}

DecoderOptions decoder_options(const pyb::kwargs& kw) {
  DecoderOptions o;
  for (auto [k, v] : kw) {
    const std::string key = pyb::str(k);
    if (key == "consistency_tolerance") o.consistency_tolerance = v.cast<double>();
    else if (key == "cg_start_residual") o.cg_start_residual = v.cast<double>();
    else if (key == "cg_tolerance") o.cg_tolerance = v.cast<double>();
    else if (key == "cg_max_iterations") o.cg_max_iterations = v.cast<int>();
    else if (key == "align_to_template") o.align_to_template = v.cast<bool>();
    else if (key == "constraint_weight") o.constraint_weight = v.cast<double>();
    else if (key == "cholesky_refactor") o.rotation_solver = v.cast<bool>() ? RotationSolver::kCholeskyRefactor : RotationSolver::kPreconditionedCG;
    else throw InputError("Decoder: unknown option '" + key + "' (DecoderOptions in encoding/relative_rotation_decoder.h)");
  }
  o.validate();
  return o;
}

Encoding encoding_arg(const EncodingTemplate& t, const pyb::handle& e, const pyb::handle& mean) {
  Eigen::VectorXd x = vector(e, "encoding");
  if (x.size() != t.encoding_size())
    throw InputError(fmt::format("encoding: {} values, the template needs {} (15 per triangle)", x.size(),
                                 t.encoding_size()));
  std::shared_ptr<const EncodingMean> m;
  if (!mean.is_none()) {
    Eigen::VectorXd mv = vector(mean, "mean");
    if (mv.size() != t.encoding_size())
      throw InputError(fmt::format("mean: {} values, expected {}", mv.size(), t.encoding_size()));
    m = EncodingMean::from_values(std::move(mv));
  }
  return Encoding{std::move(x), m};
}

class PyDecoder {
 public:
  PyDecoder(const pyb::handle& rest_V, const pyb::handle& F, const pyb::kwargs& kw) {
    auto t = make_template(rest_V, F);
    DecoderOptions o = decoder_options(kw);
    pyb::gil_scoped_release nogil;
    decoder_ = std::make_unique<RelativeRotationDecoder>(t, o);
  }
  pyb::array_t<double> encode(const pyb::handle& V, const pyb::handle& mean) const {
    const EncodingTemplate& t = decoder_->encoding_template();
    Eigen::MatrixX3d X = vertices(V, "V");
    t.check_vertices(X, "V");
    Eigen::VectorXd x;
    {
      pyb::gil_scoped_release nogil;
      x = encode_absolute(t, X);
    }
    if (!mean.is_none()) {
      Eigen::VectorXd mv = vector(mean, "mean");
      if (mv.size() != t.encoding_size())
        throw InputError(fmt::format("mean: {} values, expected {}", mv.size(), t.encoding_size()));
      x = relative_to(EncodingMean::from_values(std::move(mv)), x).values;
    }
    return to_array(x);
  }
  pyb::array_t<double> decode(const pyb::handle& e, const pyb::handle& mean) const {
    Encoding enc = encoding_arg(decoder_->encoding_template(), e, mean);
    Eigen::MatrixX3d V;
    {
      pyb::gil_scoped_release nogil;
      V = decoder_->decode(enc);
    }
    return to_array(Eigen::MatrixXd(V));
  }
  const RelativeRotationDecoder& decoder() const { return *decoder_; }

 private:
  std::unique_ptr<RelativeRotationDecoder> decoder_;
};

pyb::dict measurements_dict(const BodyMeasurements& b) {
  pyb::dict d;
  d["height_cm"] = b.height_cm;
  d["volume_l"] = b.volume_l;
  d["weight_kg"] = b.weight_kg;
  d["neck_cm"] = b.neck_cm;
  d["chest_cm"] = b.chest_cm;
  d["waist_cm"] = b.waist_cm;
  d["hips_cm"] = b.hips_cm;
  d["neck_at_cm"] = b.neck_at_cm;
  d["chest_at_cm"] = b.chest_at_cm;
  d["waist_at_cm"] = b.waist_at_cm;
  d["hips_at_cm"] = b.hips_at_cm;
  d["body_fat_pct"] = b.body_fat_pct;
  return d;
}

}  // namespace

}  // namespace bodymodel::py

using namespace bodymodel;
using namespace bodymodel::py;
namespace pyb = pybind11;
using namespace pybind11::literals;

namespace {

// The Python exception types and the translator from the C++ errors; registered before any binding
// so that every call raises InputError, NumericalError or Cancelled.
void bind_errors(pyb::module_& m) {
  static pyb::exception<InputError> input_error(m, "InputError", PyExc_ValueError);
  static pyb::exception<NumericalError> numerical_error(m, "NumericalError", PyExc_RuntimeError);
  static pyb::exception<Cancelled> cancelled(m, "Cancelled", PyExc_Exception);
  pyb::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      PyErr_SetString(input_error.ptr(), e.what());
    } catch (const NumericalError& e) {
      PyErr_SetString(numerical_error.ptr(), e.what());
    } catch (const Cancelled& e) {
      PyErr_SetString(cancelled.ptr(), "cancelled by the progress callback");
    }
  });
}

// Mesh and point-cloud file I/O: read_mesh, write_mesh, read_point_cloud.
void bind_meshes(pyb::module_& m) {
  m.def("read_mesh", [](const std::string& path) {
          Mesh mesh;
          {
            pyb::gil_scoped_release nogil;
            mesh = read_mesh(path);
          }
          return pyb::make_tuple(to_array(Eigen::MatrixXd(mesh.V)), to_array(Eigen::MatrixXi(mesh.F)));
        }, "path"_a,
        R"(read_mesh(path) -> (V, F)

Reads an OBJ, PLY (ASCII or binary) or OFF triangle mesh, chosen by extension; polygons are
triangulated as fans. V: (n, 3) float64 in the file's unit; F: (m, 3) int32, 0-based.
Raises InputError naming the file and line on a malformed file.)");
  m.def("write_mesh", [](const std::string& path, const pyb::handle& V, const pyb::handle& F, bool ascii) {
          Eigen::MatrixX3d X = vertices(V, "V", true);
          Eigen::MatrixX3i Fi = faces(F, "F", X.rows());
          pyb::gil_scoped_release nogil;
          write_mesh(path, X, Fi, {}, ascii);
        }, "path"_a, "V"_a, "F"_a, "ascii"_a = false,
        R"(write_mesh(path, V, F, ascii=False)

Writes OBJ or PLY (by extension; PLY binary little-endian unless ascii). V (n, 3), F (m, 3).
The file appears complete or not at all (written to a temporary and renamed).)");
  m.def("read_point_cloud", [](const std::string& path) {
          PointCloud c;
          {
            pyb::gil_scoped_release nogil;
            c = read_point_cloud(path);
          }
          return pyb::make_tuple(to_array(Eigen::MatrixXd(c.P)), to_array(Eigen::MatrixXd(c.N)));
        }, "path"_a,
        "read_point_cloud(path) -> (P, N): a PLY point cloud; P (n, 3), N (n, 3) unit normals or (0, 3).");
}

// MakeHuman bodies from macro sliders and body measurements: the two calls on whole bodies.
void bind_measurements(pyb::module_& m) {
  m.def("makehuman_body", [](double gender, double age, double muscle, double weight, double height,
                             double proportions, double cup, double firmness, pyb::object african,
                             pyb::object asian, pyb::object caucasian, const std::string& data) {
          MacroSettings s;
          s.gender = gender, s.age = age, s.muscle = muscle, s.weight = weight, s.height = height;
          s.proportions = proportions, s.cup = cup, s.firmness = firmness;
          if (!african.is_none()) s.set_ethnic("african", african.cast<double>());
          if (!asian.is_none()) s.set_ethnic("asian", asian.cast<double>());
          if (!caucasian.is_none()) s.set_ethnic("caucasian", caucasian.cast<double>());
          s.validate();
          MakeHuman::Body body;
          {
            pyb::gil_scoped_release nogil;
            body = makehuman(data).body(s);
          }
          return pyb::make_tuple(to_array(Eigen::MatrixXd(body.mesh.V)), to_array(Eigen::MatrixXi(body.mesh.F)));
        },
        "gender"_a = 0.5, "age"_a = 0.5, "muscle"_a = 0.5, "weight"_a = 0.5, "height"_a = 0.5,
        "proportions"_a = 0.5, "cup"_a = 0.5, "firmness"_a = 0.5, "african"_a = pyb::none(),
        "asian"_a = pyb::none(), "caucasian"_a = pyb::none(), "makehuman_dir"_a = "",
        R"(makehuman_body(gender=0.5, age=0.5, ..., makehuman_dir='') -> (V, F)

The MakeHuman hm08 body of these macro sliders (each in [0, 1]; gender 0 female … 1 male, age
0.5 = 25 years) in the rest A-pose, as `bodymodel makehuman-body` writes it: V (13380, 3) mm,
F (26756, 3). An ethnic weight rescales the other two so they sum to 1. The data folder
(default $BODYMODEL_DATA/makehuman) is loaded once per process (≈ 0.3 s).)");

  m.def("measure", [](const pyb::handle& V, const pyb::handle& F, const std::string& sex, int up_axis,
                      double density_kg_per_l, double mm_per_unit, const std::string& standard) -> pyb::dict {
          if (!standard.empty() && standard != "nhanes" && standard != "ansur2")
            throw InputError("standard: expected '', 'nhanes' or 'ansur2', got '" + standard + "'");
          Eigen::MatrixX3d X = vertices(V, "V");
          if (standard == "ansur2") {
            if (X.rows() != kSurveyTemplateVertexCount)
              throw InputError("V: standard='ansur2' needs a body with the hm08 template's topology (" +
                               std::to_string(kSurveyTemplateVertexCount) + " vertices, got " +
                               std::to_string(X.rows()) + ")");
            X *= mm_per_unit;
            std::vector<SurveyValue> cols;
            {
              pyb::gil_scoped_release nogil;
              cols = ansur2_columns(ansur_measurer(), X, makehuman("").skeleton_from_body(X), "V");
            }
            pyb::dict d;  // as `bodymodel measure --standard ansur2 --json`
            for (const SurveyValue& c : cols) d[pyb::str(c.column)] = c.value;
            return d;
          }
          Eigen::MatrixX3i Fi = faces(F, "F", X.rows());
          MeasureOptions o;
          o.up_axis = up_axis, o.density_kg_per_l = density_kg_per_l, o.mm_per_unit = mm_per_unit;
          const Sex s = parse_sex(sex);
          BodyMeasurements b;
          {
            pyb::gil_scoped_release nogil;
            b = measure_body(X, Fi, s, o);
          }
          if (standard == "nhanes") {
            pyb::dict d;  // as `bodymodel measure --standard nhanes --json`
            for (const SurveyValue& c : nhanes_columns(b, "V")) d[pyb::str(c.column)] = c.value;
            return d;
          }
          return measurements_dict(b);
        }, "V"_a, "F"_a, "sex"_a = "unknown", "up_axis"_a = 1, "density_kg_per_l"_a = 1.01,
        "mm_per_unit"_a = 1.0, "standard"_a = "",
        R"(measure(V, F, sex='unknown', up_axis=1, density_kg_per_l=1.01, mm_per_unit=1.0, standard='') -> dict

Body measurements of a closed, outward-oriented mesh in the standard pose, as `bodymodel
measure`: height_cm (extent along the up axis), volume_l, weight_kg (volume × density), the
neck/chest/waist/hips girths in cm (convex hull of the torso section) and the heights they
were found at (*_at_cm), body_fat_pct (U.S. Navy formula; NaN unless sex is female/male).
V (n, 3) in units of mm_per_unit millimetres, F (m, 3). standard='nhanes' returns the NHANES
columns instead (BMXHT, BMXWT, BMXWAIST, BMXHIP, BMXARMC, BMXARML, BMXLEG; cm and kg), as
`bodymodel measure --standard nhanes`; they need the template's topology. standard='ansur2'
returns 23 ANSUR II columns (stature, weightkg, chestcircumference, ...; mm, weightkg in kg) as
`bodymodel measure --standard ansur2` (docs/measurements.md); F is then the template's.)");
}

// The reusable Decoder class and the one-off encode/decode of the relative rotation encoding.
void bind_encoding(pyb::module_& m) {
  pyb::class_<PyDecoder>(m, "Decoder", R"(A reusable relative-rotation decoder for one template.

Decoder(rest_V, F, **options): the one-time set-up (adjacency, factorisations) for the template
rest_V (n, 3) mm with triangles F (m, 3). Options are DecoderOptions
(encoding/relative_rotation_decoder.h): consistency_tolerance, cg_start_residual, cg_tolerance,
cg_max_iterations, align_to_template, constraint_weight, cholesky_refactor (bool).
Thread-safe: decode() may run from several Python threads at once (it releases the GIL).)")
      .def(pyb::init<const pyb::handle&, const pyb::handle&, const pyb::kwargs&>(), "rest_V"_a, "F"_a)
      .def("encode", &PyDecoder::encode, "V"_a, "mean"_a = pyb::none(),
           R"(encode(V, mean=None) -> (15·m,) float64

The relative rotation encoding of V (n, 3), same vertex order as the template: per triangle
three relative-rotation vectors (radians) then the six stretch entries (layout in
encoding/relative_rotation_encoding.h). With `mean` (15·m absolute values) the result is
relative to it, as `bodymodel encode` stores rows relative to the set's mean.)")
      .def("decode", &PyDecoder::decode, "encoding"_a, "mean"_a = pyb::none(),
           R"(decode(encoding, mean=None) -> V (n, 3)

Vertex positions of an encoding (15·m values; relative to `mean` when given), rigidly aligned
to the template's rest vertices. Two sparse solves (rotations, then positions).)")
      .def_property_readonly("vertex_count", [](const PyDecoder& d) { return d.decoder().encoding_template().vertex_count(); })
      .def_property_readonly("triangle_count", [](const PyDecoder& d) { return d.decoder().encoding_template().triangle_count(); })
      .def_property_readonly("last_decode_ms", [](const PyDecoder& d) { return d.decoder().last_timing().total_ms; },
                             "Wall-clock milliseconds of the most recent decode.");

  m.def("encode", [](const pyb::handle& V, const pyb::handle& F, const pyb::handle& rest_V) {
          auto t = make_template(rest_V, F);
          Eigen::MatrixX3d X = vertices(V, "V");
          t->check_vertices(X, "V");
          pyb::gil_scoped_release nogil;
          Eigen::VectorXd x = encode_absolute(*t, X);
          pyb::gil_scoped_acquire gil;
          return to_array(x);
        }, "V"_a, "F"_a, "rest_V"_a,
        R"(encode(V, F, rest_V) -> (15·m,) float64

Absolute relative rotation encoding of V (n, 3) against the template (rest_V (n, 3), F (m, 3)).
For many meshes build a Decoder once and call its encode().)");
  m.def("decode", [](const pyb::handle& e, const pyb::handle& F, const pyb::handle& rest_V, const pyb::handle& mean) {
          auto t = make_template(rest_V, F);
          Encoding enc = encoding_arg(*t, e, mean);
          pyb::gil_scoped_release nogil;
          Eigen::MatrixX3d V = decode(t, enc);
          pyb::gil_scoped_acquire gil;
          return to_array(Eigen::MatrixXd(V));
        }, "encoding"_a, "F"_a, "rest_V"_a, "mean"_a = pyb::none(),
        R"(decode(encoding, F, rest_V, mean=None) -> V (n, 3)

One-off decode (builds a Decoder each call: for many decodes keep a Decoder).)");
}

}  // namespace

PYBIND11_MODULE(bodymodel, m) {
  m.doc() = R"(bodymodel: body scans, a PCA body model with semantic labels, and skinning, on numpy arrays.

Units: millimetres, +y up, bodies face +z. Vertices are float64 (n, 3) arrays, triangles int32
(m, 3) arrays of 0-based indices (any integer dtype is accepted; float indices are refused).
Errors raise bodymodel.InputError (a ValueError) or bodymodel.NumericalError with the command
line's one-line messages. Long calls release the GIL and take progress=callable(fraction, what);
returning False from it stops the work with bodymodel.Cancelled. Reference: docs/python.md.)";

  bind_errors(m);

  m.def("data_path", [](const std::string& rel) { return data_file(rel).string(); }, "relative"_a = "",
        "The shared data folder ($BODYMODEL_DATA, default set at build time) joined with `relative`.");

  bind_meshes(m);
  bind_measurements(m);
  bind_encoding(m);
  bind_model(m);
  bind_skinning(m);
  bind_regression(m);
  bind_registration(m);
  bind_markers(m);
}
