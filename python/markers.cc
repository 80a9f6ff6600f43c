// Dense-marker captures (markers/): reading and writing C3D and TRC, and cleaning (issue 38).
// A capture is a dict {labels, rate, first_frame, xyz}: xyz a (frames, markers, 3) float64 array
// in millimetres, NaN where a sample is missing.
#include <fmt/format.h>

#include <cmath>

#include "core/error.h"
#include "markers/clean.h"
#include "markers/marker_data.h"
#include "python/common.h"

namespace bodymodel::py {

namespace {

using namespace pybind11::literals;

pyb::dict capture_dict(const MarkerData& d) {
  pyb::array_t<double> xyz({static_cast<pyb::ssize_t>(d.frame_count()), static_cast<pyb::ssize_t>(d.marker_count()),
                            pyb::ssize_t{3}});
  auto w = xyz.mutable_unchecked<3>();
  for (int f = 0; f < d.frame_count(); ++f)
    for (int m = 0; m < d.marker_count(); ++m)
      for (int c = 0; c < 3; ++c) w(f, m, c) = d.xyz(f, 3 * m + c);
  return pyb::dict("labels"_a = d.labels, "rate"_a = d.rate, "first_frame"_a = d.first_frame, "xyz"_a = xyz);
}

// labels and a (frames, markers, 3) array (NaN = missing) as a MarkerData; InputError naming `what`.
MarkerData capture_of(const std::vector<std::string>& labels, const pyb::handle& xyz, double rate, int first_frame,
                      const std::string& what) {
  auto a = DoubleArray::ensure(xyz);
  if (!a) {
    PyErr_Clear();
    throw InputError(what + ": expected a numeric (frames, markers, 3) array");
  }
  if (a.ndim() != 3 || a.shape(2) != 3 || a.shape(1) != static_cast<pyb::ssize_t>(labels.size()))
    throw InputError(fmt::format("{}: expected a (frames, {}, 3) array (one column of 3 per label), got {} dimensions",
                                 what, labels.size(), a.ndim()));
  MarkerData d;
  d.labels = labels;
  d.rate = rate;
  d.first_frame = first_frame;
  d.xyz.resize(a.shape(0), 3 * a.shape(1));
  auto r = a.unchecked<3>();
  for (pyb::ssize_t f = 0; f < a.shape(0); ++f)
    for (pyb::ssize_t m = 0; m < a.shape(1); ++m)
      for (int c = 0; c < 3; ++c) d.xyz(f, 3 * m + c) = r(f, m, c);
  check_marker_data(d, what);
  return d;
}

pyb::object json_object(const nlohmann::json& j) { return pyb::module_::import("json").attr("loads")(j.dump()); }

pyb::tuple clean(const std::vector<std::string>& labels, const pyb::handle& xyz, double rate, int reference_frame,
                 int neighbours, double merge_tolerance, double piece_tolerance, int smooth, const pyb::object& truth,
                 const pyb::object& progress) {
  const MarkerData capture = capture_of(labels, xyz, rate, 1, "xyz");
  MarkerData truth_data;
  if (!truth.is_none()) {
    const pyb::dict t = truth.cast<pyb::dict>();
    truth_data = capture_of(t["labels"].cast<std::vector<std::string>>(), t["xyz"], rate, 1, "truth");
  }
  CleanOptions o;
  o.reference_frame = reference_frame;
  o.neighbours = neighbours;
  o.merge_tolerance = merge_tolerance;
  o.piece_tolerance = piece_tolerance;
  o.smooth_iterations = smooth;
  const ProgressCallback cb = progress_callback(progress);
  CleanResult r;
  {
    pyb::gil_scoped_release nogil;
    r = clean_markers(capture, o, cb ? std::function<void(double)>([&](double f) { report_progress(cb, f, "clean"); })
                                     : std::function<void(double)>());
  }
  nlohmann::json report = clean_report_json(r.report);
  if (!truth.is_none()) report["evaluation"] = evaluation_json(evaluate_cleaning(capture, r, truth_data));
  return pyb::make_tuple(capture_dict(r.cleaned), json_object(report));
}

}  // namespace

void bind_markers(pyb::module_& m) {
  m.def(
      "read_markers",
      [](const std::string& path) {
        MarkerData d;
        {
          pyb::gil_scoped_release nogil;
          d = read_markers(path);
        }
        return capture_dict(d);
      },
      "path"_a,
      "read_markers(path) -> {labels, rate, first_frame, xyz}: a .c3d or .trc capture; xyz (frames, markers, 3) mm, "
      "NaN where a sample is missing (markers/marker_data.h). Releases the GIL.");
  m.def(
      "write_markers",
      [](const std::string& path, const std::vector<std::string>& labels, const pyb::handle& xyz, double rate,
         int first_frame) { write_markers(path, capture_of(labels, xyz, rate, first_frame, "xyz")); },
      "path"_a, "labels"_a, "xyz"_a, "rate"_a = 100.0, "first_frame"_a = 1,
      "write_markers(path, labels, xyz, rate=100, first_frame=1): .c3d (float, Intel) or .trc by extension, "
      "atomically; xyz (frames, markers, 3) mm, NaN = missing.");
  m.def("clean_markers", &clean, "labels"_a, "xyz"_a, "rate"_a = 100.0, "reference_frame"_a = 0, "neighbours"_a = 6,
        "merge_tolerance"_a = 0.5, "piece_tolerance"_a = 0.6, "smooth"_a = 2, "truth"_a = pyb::none(),
        "progress"_a = pyb::none(),
        "clean_markers(labels, xyz, rate=100, ...) -> (cleaned, report): `bodymodel markers clean` "
        "(markers/clean.h). Labelled markers (not starting with '*') complete in reference_frame, pieces '*N' "
        "merged, holes filled, smoothed; cleaned is a capture dict (every labelled marker at every frame), report the "
        "CLI's JSON report as a dict. truth: a capture dict (every marker at every frame) adds report['evaluation']. "
        "Releases the GIL.");
}

}  // namespace bodymodel::py
