// bodymodel.register_scan: the registration of one scan as `bodymodel register` runs it
// (registration/job.h: the same template, options, fold repair and plausibility check).
#include <fmt/format.h>

#include <algorithm>
#include <map>
#include <optional>
#include <nlohmann/json.hpp>
#include <mutex>

#include "core/error.h"
#include "core/io/shape_space_file.h"
#include "core/landmarks.h"
#include "python/common.h"
#include "registration/evaluation.h"
#include "registration/job.h"
#include "registration/metrics.h"

namespace bodymodel::py {

namespace {

using namespace pybind11::literals;

// The macro sliders of a `template` argument (None: MakeHuman's default body).
std::optional<MacroSettings> template_sliders(const pyb::handle& tmpl) {
  if (tmpl.is_none()) return std::nullopt;
  if (!pyb::isinstance<pyb::dict>(tmpl))
    throw InputError("template: expected None or a dict of MakeHuman macro sliders {gender: 0..1, ...}");
  nlohmann::json j = nlohmann::json::object();
  for (auto [k, v] : tmpl.cast<pyb::dict>()) {
    const std::string name = pyb::str(k);
    try {
      j[name] = v.cast<double>();
    } catch (const pyb::cast_error&) {
      j[name] = std::string(pyb::repr(v));  // MacroSettings::from_json names it as not a number
    }
  }
  return MacroSettings::from_json(j);
}

// The template, kept for the next call (loading MakeHuman's data takes a while): the default body
// per shape_fit flag, and the last custom template.
std::shared_ptr<const RegistrationTemplate> cached_template(const RegistrationJobOptions& o) {
  static std::mutex mutex;
  static std::map<std::string, std::shared_ptr<const RegistrationTemplate>> cache;
  std::string key = o.shape_fit ? "shape:" : "noshape:";
  if (o.start_shape) key += o.start_shape->to_json().dump();
  // A learned space is read per call (the file may change), so its template is not cached.
  if (o.learned_space) return std::make_shared<const RegistrationTemplate>(registration_template(o));
  std::lock_guard lock(mutex);
  auto& t = cache[key];
  if (!t) {
    t = std::make_shared<const RegistrationTemplate>(registration_template(o));
    if (o.start_shape)  // one custom template at a time
      for (auto it = cache.begin(); it != cache.end();)
        it = it->first.find('{') != std::string::npos && it->first != key ? cache.erase(it) : std::next(it);
  }
  return t;
}

std::vector<Landmark> landmarks_from(const pyb::handle& h) {
  if (!pyb::isinstance<pyb::dict>(h)) throw InputError("landmarks: expected a dict {name: (x, y, z)}");
  std::vector<Landmark> out;
  for (auto [k, v] : h.cast<pyb::dict>()) {
    Landmark l;
    l.name = pyb::str(k);
    l.vertex = template_landmark_vertex(registration_landmarks(), l.name, "landmarks");
    Eigen::VectorXd t = vector(v, "landmark '" + l.name + "'");
    if (t.size() != 3) throw InputError("landmarks: landmark '" + l.name + "' must be three numbers (x, y, z)");
    l.target = t;
    out.push_back(std::move(l));
  }
  return out;
}

pyb::tuple register_one(const pyb::handle& points, const pyb::handle& normals, const pyb::handle& landmarks,
                        const pyb::handle& tmpl,
                        const std::string& schedule, int fast_steps, double fast_k_end, double transform_length,
                        double scan_unit_mm, bool pose_only, const std::string& pose_joints, bool hand_stage,
                        bool proportions, bool shape_fit, bool proportions_with_shape, bool repair_folds,
                        const std::string& shape_space, const std::string& what, const pyb::object& progress) {
  RegistrationJobOptions job;
  job.schedule = schedule;
  job.fast_steps = fast_steps;
  job.fast_k_end = fast_k_end;
  job.transform_length = transform_length;
  job.pose_only = pose_only;
  job.pose_joints = pose_joints;
  job.hand_stage = hand_stage;
  job.proportions = proportions;
  job.shape_fit = shape_fit;
  job.proportions_with_shape = proportions_with_shape;
  job.folds = repair_folds ? FoldRepair::local : FoldRepair::keep;
  job.start_shape = template_sliders(tmpl);
  if (!shape_space.empty()) job.learned_space = std::make_shared<const ShapeSpace>(read_shape_space(shape_space));
  const RegistrationSetup setup = registration_setup(job);  // validates, naming the option
  if (!(scan_unit_mm > 0) || !std::isfinite(scan_unit_mm))
    throw InputError(fmt::format("scan_unit_mm must be a positive number, got {}", scan_unit_mm));
  PointCloud scan;
  scan.P = vertices(points, "points");
  if (!normals.is_none()) {
    scan.N = vertices(normals, "normals", true);
    if (scan.N.rows() != 0 && scan.N.rows() != scan.P.rows())
      throw InputError(fmt::format("normals: {} rows, expected one per point ({}) or none", scan.N.rows(),
                                   scan.P.rows()));
  }
  std::vector<Landmark> lm = landmarks_from(landmarks);
  scan.P *= scan_unit_mm;
  for (auto& l : lm) l.target *= scan_unit_mm;

  const std::shared_ptr<const RegistrationTemplate> held = cached_template(job);
  const RegistrationTemplate& tpl = *held;
  ProgressCallback cb = progress_callback(progress);
  RegistrationJobResult job_result;
  {
    pyb::gil_scoped_release nogil;
    job_result = run_registration_job(tpl, setup, scan, lm, what, cb);
  }
  const RegistrationResult& r = job_result.registration;
  const RegistrationSummary& s = job_result.summary;
  const int local_folds = job_result.local_folds_repaired;
  pyb::dict d;
  d["faces"] = to_array(Eigen::MatrixXi(tpl.mesh.F));
  d["posed_template"] = to_array(Eigen::MatrixXd(r.pose.V));
  d["rest_template"] = to_array(Eigen::MatrixXd(r.rest.V));
  d["scale"] = r.pose.scale;
  pyb::list rot;
  for (const auto& R : r.pose.pose.rotations) rot.append(to_array(Eigen::MatrixXd(R)));
  d["bone_names"] = tpl.skeleton.names;
  d["bone_rotations"] = rot;
  d["root_translation"] = to_array(Eigen::VectorXd(r.pose.pose.root_translation));
  d["points"] = scan.P.rows();
  d["normals_estimated"] = s.scan.normals_estimated;
  d["landmarks"] = lm.size();
  d["pose_icp_iterations"] = s.pose.icp_iterations;
  d["pose_rms_mm"] = s.pose.rms;
  d["pose_landmark_rms_mm"] = s.pose.landmark_rms;
  d["pose_two_sided_mm"] = s.pose.two_sided_mm;
  d["pose_joints"] = job_result.pose_joints;
  d["nonrigid_iterations"] = s.nonrigid.iterations;
  d["data_rms_mm"] = s.nonrigid.data_rms;
  d["landmark_rms_mm"] = s.nonrigid.landmark_rms;
  d["matched_vertices"] = s.nonrigid.matched_vertices;
  d["plane_matches"] = s.nonrigid.plane_matches;
  d["pose_seconds"] = s.pose.seconds;
  d["nonrigid_seconds"] = s.nonrigid.seconds;
  d["seconds"] = s.seconds;
  d["folded_triangles_repaired"] = s.folded_triangles;
  d["local_folds_repaired"] = local_folds;
  // As the verb's registration.csv: local folds left (against the fitted rest body) and the
  // farthest the untangling moved a vertex (0 without repair_local_folds).
  const std::vector<char> left = locally_folded_triangles(r.V, r.rest.V, tpl.mesh.F);
  d["local_folds"] = int(std::count(left.begin(), left.end(), 1));
  d["untangle_max_mm"] = job_result.untangle.max_displacement;
  d["shape_rounds"] = s.shape_rounds;
  d["shape_seconds"] = s.shape_seconds;
  if (r.shape) {
    const MacroSettings& m = *r.shape;
    d["shape"] = pyb::dict("gender"_a = m.gender, "age"_a = m.age, "muscle"_a = m.muscle, "weight"_a = m.weight,
                           "height"_a = m.height, "proportions"_a = m.proportions, "cup"_a = m.cup);
  } else {
    d["shape"] = pyb::none();
  }
  if (r.shape_coefficients.size() > 0) d["shape_space_coefficients"] = to_array(Eigen::VectorXd(r.shape_coefficients));
  return pyb::make_tuple(to_array(Eigen::MatrixXd(r.V)), d);
}

// The evaluator of MakeHuman's default body (the template every registration has), built once.
const RegistrationEvaluator& template_evaluator() {
  static const RegistrationEvaluator e = [] {
    const MakeHuman::Body b = MakeHuman::load().body(MacroSettings{});
    return RegistrationEvaluator(b.mesh, b.skeleton, b.weights);
  }();
  return e;
}

pyb::dict evaluate_registration(const pyb::handle& V, const pyb::handle& truth, const pyb::handle& scan) {
  const Eigen::MatrixX3d R = vertices(V, "V"), T = vertices(truth, "truth");
  const Eigen::MatrixX3d P = scan.is_none() ? T : vertices(scan, "scan");
  ScanEvaluation e;
  {
    pyb::gil_scoped_release nogil;
    e = template_evaluator().evaluate_scan(R, T, P);
  }
  const RegistrationErrors& x = e.errors;
  std::map<std::string, int> regions;
  for (const FlippedTriangle& f : e.flipped) ++regions[f.region];
  pyb::dict by_region;
  for (const auto& [region, count] : regions) by_region[pyb::str(region)] = count;
  return pyb::dict("correspondence_mean_mm"_a = x.correspondence_mean, "correspondence_p95_mm"_a = e.correspondence_p95,
                   "correspondence_max_mm"_a = x.correspondence_max, "surface_mean_mm"_a = x.surface_mean,
                   "surface_max_mm"_a = x.surface_max, "hole_vertices"_a = x.hole_vertices,
                   "hole_mean_mm"_a = x.hole_mean, "hole_max_mm"_a = x.hole_max,
                   "flipped_triangles"_a = x.flipped_triangles, "flipped_unseen"_a = x.flipped_unseen,
                   "flipped_where_truth_folded"_a = e.flipped_truth_folded, "flipped_by_region"_a = by_region,
                   "folded_in_registration"_a = e.folded_registration, "folded_in_truth"_a = e.folded_truth,
                   "vertex_errors_mm"_a = to_array(Eigen::VectorXd(x.vertex_errors)));
}

}  // namespace

void bind_registration(pyb::module_& m) {
  m.def("evaluate_registration", &evaluate_registration, "V"_a, "truth"_a, "scan"_a = pyb::none(),
        R"(evaluate_registration(V, truth, scan=None) -> dict

A registration of MakeHuman's template against its ground truth, as `bodymodel eval-registration`
measures each scan (docs/evaluation.md): V and truth (13380, 3) mm in the template's topology;
scan (n, 3) the scan's points for the hole mask (None: the truth's vertices, no holes). Returns
correspondence_mean_mm / _p95_mm / _max_mm, surface_mean_mm / _max_mm, hole_vertices, hole_mean_mm,
hole_max_mm, flipped_triangles (with flipped_unseen, flipped_where_truth_folded and
flipped_by_region), folded_in_registration, folded_in_truth and vertex_errors_mm (13380,).)");
  const NonrigidOptions nr;
  m.def("register_scan", &register_one, "points"_a, "normals"_a = pyb::none(), pyb::kw_only(),
        "landmarks"_a, "template"_a = pyb::none(), "schedule"_a = "fast", "fast_steps"_a = nr.fast_steps, "fast_stiffness_end"_a = nr.fast_k_end,
        "transform_length"_a = nr.normalization_length, "scan_unit_mm"_a = 1.0, "pose_only"_a = false,
        "pose_joints"_a = "segment", "hand_stage"_a = true, "proportions"_a = true, "shape_fit"_a = true,
        "proportions_with_shape"_a = false, "repair_local_folds"_a = false, "shape_space"_a = "", "what"_a = "scan",
        "progress"_a = pyb::none(),
        R"(register_scan(points, normals=None, *, landmarks, template=None, schedule='fast', ..., progress=None) -> (V, summary)

Registers the template (MakeHuman's default body, its skeleton and weights; MakeHuman's macro
sliders as its shape space unless shape_fit=False) to one scan, as `bodymodel register` does for
each scan of a database (same defaults; docs/registration.md): skeleton pose fit alternated with a
fit of the macro sliders, then the non-rigid fit, the fold repair and the plausibility check.
points: (n, 3) scan points; normals: (n, 3) unit normals or None (estimated, unoriented);
landmarks: {name: (x, y, z)} scan positions of the template's landmarks (head_top, l_knee, ...;
the names of a database's <id>.landmarks.json); scan_unit_mm: mm per unit of points/landmarks.
template: None (MakeHuman's default body, as the verb) or MakeHuman macro sliders for the start
body, e.g. {'gender': 1.0, 'height': 0.7} (the others default; keys of `bodymodel makehuman-body`).
Keywords match the verb's flags: schedule 'fast'|'paper', fast_steps, fast_stiffness_end,
transform_length (mm), pose_only, pose_joints 'segment'|'bone'|'best', hand_stage,
proportions, shape_fit, proportions_with_shape, repair_local_folds, shape_space (a file of
`bodymodel shape-space`: the shape fit moves in that space learned from real bodies; the summary
then has shape_space_coefficients). `what` names the scan in
error messages. Returns V (13380, 3) mm in the template's topology and a summary dict: faces
(the template's triangles), posed_template, scale, bone_names, bone_rotations, shape (fitted
sliders or None) and the columns of the verb's registration.csv (pose_rms_mm, data_rms_mm, ...).
A scan that is not a body raises InputError ('registration failed: ...'). Runs with the GIL
released; progress(fraction, what). Needs MakeHuman's data ($BODYMODEL_DATA/makehuman).)");
}

}  // namespace bodymodel::py
