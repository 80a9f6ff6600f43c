// bodymodel.register_scan: the registration of one scan (registration/register_scan.h) with the
// template and options of `bodymodel register` (tools/pipeline/registration_setup.h, compiled
// into the module) and the same per-scan steps as the verb: optional local fold repair, then the
// plausibility check that fails a scan that is not a body.
#include <fmt/format.h>

#include <map>
#include <optional>
#include <nlohmann/json.hpp>
#include <mutex>

#include "core/error.h"
#include "core/landmarks.h"
#include "python/common.h"
#include "registration/fit_check.h"
#include "registration/local_fold_repair.h"
#include "registration/register_scan.h"
#include "tools/pipeline/registration_setup.h"

namespace bodymodel::py {

namespace {

using namespace pybind11::literals;

// The template and options: the verbs' (MakeHuman's default body) or MakeHuman's body of the given
// macro sliders. Kept for the next call (MakeHuman's data takes ≈ 0.5 s to load): the verbs' set-up
// per shape_fit flag, and the last custom template.
std::shared_ptr<const RegistrationSetup> setup(bool shape_fit, const pyb::handle& tmpl) {
  static std::mutex mutex;
  static std::map<std::string, std::shared_ptr<const RegistrationSetup>> cache;
  std::string key = shape_fit ? "shape:" : "noshape:";
  MacroSettings settings;
  if (!tmpl.is_none()) {
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
    settings = MacroSettings::from_json(j);
    key += settings.to_json().dump();
  }
  std::lock_guard lock(mutex);
  auto& s = cache[key];
  if (!s) {
    RegistrationFlags flags;
    flags.no_shape_fit = !shape_fit;
    auto r = std::make_shared<RegistrationSetup>(makehuman_registration_setup(flags));
    if (!tmpl.is_none()) {
      // As makehuman_registration_setup, from another body of the same shape space.
      std::optional<MakeHuman> loaded;  // without the shape fit the set-up keeps no MakeHuman
      if (!r->tpl.shape_space) loaded = MakeHuman::load();
      MakeHuman::Body body = (r->tpl.shape_space ? *r->tpl.shape_space : *loaded).body(settings);
      r->tpl.mesh = body.mesh;
      r->tpl.skeleton = body.skeleton;
      r->tpl.weights = body.weights;
      r->tpl.shape_start = settings;
      for (auto it = cache.begin(); it != cache.end();)  // one custom template at a time
        it = it->first.find('{') != std::string::npos && it->first != key ? cache.erase(it) : std::next(it);
    }
    s = std::move(r);
  }
  return s;
}

std::vector<Landmark> landmarks_from(const pyb::handle& h) {
  if (!pyb::isinstance<pyb::dict>(h)) throw InputError("landmarks: expected a dict {name: (x, y, z)}");
  std::vector<Landmark> out;
  for (auto [k, v] : h.cast<pyb::dict>()) {
    Landmark l;
    l.name = pyb::str(k);
    l.vertex = template_landmark_vertex(body_landmarks(), l.name, "landmarks");
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
                        const std::string& what, const pyb::object& progress) {
  // The verb's checks and messages (tools/verbs/registration_register.cc).
  if (schedule != "paper" && schedule != "fast")
    throw InputError("schedule: expected 'paper' or 'fast', got '" + schedule + "'");
  if (pose_joints != "segment" && pose_joints != "bone" && pose_joints != "best")
    throw InputError("pose_joints: expected 'segment', 'bone' or 'best', got '" + pose_joints + "'");
  if (!(scan_unit_mm > 0)) throw InputError("--scan-unit-mm must be positive");
  if (fast_steps < 1) throw InputError("--fast-steps must be at least 1");
  if (!(fast_k_end > 0) || !(transform_length > 0))
    throw InputError("--fast-stiffness-end and --transform-length must be positive");
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

  const std::shared_ptr<const RegistrationSetup> held = setup(shape_fit, tmpl);
  const RegistrationSetup& base = *held;
  RegistrationOptions o = base.options;
  o.nonrigid.schedule = schedule == "paper" ? NonrigidSchedule::paper : NonrigidSchedule::fast;
  o.nonrigid.fast_steps = fast_steps;
  o.nonrigid.fast_k_end = fast_k_end;
  o.skip_nonrigid = pose_only;
  o.fit_proportions = proportions;
  o.nonrigid.normalization_length = transform_length;
  o.proportions_with_shape = proportions_with_shape;
  if (pose_joints == "bone") o.pose.parameters = bone_pose_parameters();
  if (pose_joints == "segment") o.pose.parameters = segment_pose_parameters();
  if (pose_joints == "best") {
    o.pose.parameters = segment_pose_parameters();
    o.pose_alternatives.push_back(o.pose);
    o.pose_alternatives.back().parameters = bone_pose_parameters();
  }
  if (hand_stage) {
    if (o.pose.parameters.empty()) o.pose.parameters = default_pose_parameters();
    o.pose.parameters = with_hand_stage(o.pose.parameters);
    for (auto& alt : o.pose_alternatives) alt.parameters = with_hand_stage(alt.parameters);
  }
  const RegistrationTemplate& tpl = base.tpl;
  ProgressCallback cb = progress_callback(progress);
  RegistrationSummary s;
  RegistrationResult r;
  int local_folds = 0;
  {
    pyb::gil_scoped_release nogil;
    r = register_scan(tpl, scan, lm, o, what, &s, cb);
    if (repair_folds && !pose_only) local_folds = repair_local_folds(r.V, r.rest.V, tpl.mesh.F).folded_before;
    if (!pose_only) {
      const FitCheck fc = check_registration_fit(r.V, r.pose.V, r.rest.V, tpl.mesh.F, scan);
      if (!fc.plausible) throw InputError(what + ": registration failed: " + fc.reason);
    }
  }
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
  d["pose_joints"] = pose_joints == "best" ? (s.pose_choice == 0 ? "segment" : "bone") : pose_joints;
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
  d["shape_rounds"] = s.shape_rounds;
  d["shape_seconds"] = s.shape_seconds;
  if (r.shape) {
    const MacroSettings& m = *r.shape;
    d["shape"] = pyb::dict("gender"_a = m.gender, "age"_a = m.age, "muscle"_a = m.muscle, "weight"_a = m.weight,
                           "height"_a = m.height, "proportions"_a = m.proportions, "cup"_a = m.cup);
  } else {
    d["shape"] = pyb::none();
  }
  return pyb::make_tuple(to_array(Eigen::MatrixXd(r.V)), d);
}

}  // namespace

void bind_registration(pyb::module_& m) {
  const NonrigidOptions nr;
  m.def("register_scan", &register_one, "points"_a, "normals"_a = pyb::none(), pyb::kw_only(),
        "landmarks"_a, "template"_a = pyb::none(), "schedule"_a = "fast", "fast_steps"_a = nr.fast_steps, "fast_stiffness_end"_a = nr.fast_k_end,
        "transform_length"_a = nr.normalization_length, "scan_unit_mm"_a = 1.0, "pose_only"_a = false,
        "pose_joints"_a = "segment", "hand_stage"_a = true, "proportions"_a = true, "shape_fit"_a = true,
        "proportions_with_shape"_a = false, "repair_local_folds"_a = false, "what"_a = "scan",
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
proportions, shape_fit, proportions_with_shape, repair_local_folds. `what` names the scan in
error messages. Returns V (13380, 3) mm in the template's topology and a summary dict: faces
(the template's triangles), posed_template, scale, bone_names, bone_rotations, shape (fitted
sliders or None) and the columns of the verb's registration.csv (pose_rms_mm, data_rms_mm, ...).
A scan that is not a body raises InputError ('registration failed: ...'). Runs with the GIL
released; progress(fraction, what). Needs MakeHuman's data ($BODYMODEL_DATA/makehuman).)");
}

}  // namespace bodymodel::py
