// Pictures of a dense-marker capture for the demo's report (issue 38), rendered headless by
// tools/render: the cleaned markers' trails over the clip with the samples the cleaning filled in
// another colour (from `markers clean`'s output and the gaps its report lists), and the skin driven
// by the cleaned markers (`markers deform --write-every`) beside the true mesh of the same frame.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "markers/clean.h"
#include "markers/marker_data.h"
#include "tools/render/render.h"

namespace bodymodel {

// The trails' colours (before shading; a ribbon facing the camera is drawn at about these).
inline const Eigen::Vector3d kTrailSeen{0.32, 0.42, 0.62};    // measured (or merged) samples
inline const Eigen::Vector3d kTrailFilled{0.95, 0.42, 0.05};  // filled by the cleaning

// Frames × markers, true where a gap of `gaps` covers the sample (markers matched by label).
// InputError naming the marker or frames when a gap does not fit `d`.
std::vector<std::vector<char>> filled_mask(const MarkerData& d, const std::vector<GapRecord>& gaps);

// The gaps of a `markers clean` report (its "gaps" list); InputError naming the file when it is
// not such a report (e.g. written before the report listed its gaps).
std::vector<GapRecord> read_clean_gaps(const std::filesystem::path& report);

// Every marker's trail over frames [first, first + count) of a complete capture (every sample
// present), as ribbons about `width_mm` wide facing the camera: a segment is drawn in kTrailFilled
// when either of its samples is filled (`filled` as from filled_mask), else kTrailSeen, the filled
// ones a little nearer the camera so they show where trails cross. +y up; camera as render_mesh's.
// InputError when a sample in the range is missing or the range is empty.
Image marker_trails_picture(const MarkerData& d, const std::vector<std::vector<char>>& filled, int first, int count,
                            int width, int height, double width_mm = 6, const Camera& camera = {});

// The true mesh (grey) and the skin (coloured by each vertex's distance to the truth, blue 0 →
// red ≥ scale) side by side at one scale, a colour bar under them. Same vertices in the same
// order; distances in the meshes' unit times mm_per_unit. InputError when the sizes differ.
Image skin_beside_truth_picture(const Eigen::MatrixX3d& truth, const Eigen::MatrixX3d& skin, const Eigen::MatrixX3i& F,
                                double mm_per_unit, double scale_mm, int cell_width, int height);

// The demo's marker stage, as written under `dir`: dir/clean.trc and dir/clean.json (markers
// clean), dir/deform/deform.json, errors.csv and park_FFFFF.obj (markers deform --write-every),
// and `meshes`, the truth mesh files the capture was simulated from (mesh frame m = capture frame
// m · frames_per_mesh).
struct MarkerPictures {
  Image trails, skin;
  int frames = 0, markers = 0, gaps = 0;
  long filled_samples = 0;
  int held_out_capture_frame = -1, held_out_mesh = -1;  // the skin picture's frame
  double park_mean_mm = 0;                               // Park's mean vertex error on it
};
MarkerPictures marker_pictures(const std::filesystem::path& dir, const std::vector<std::filesystem::path>& meshes,
                               int frames_per_mesh, double mm_per_unit);

// The marker stage's figures as CSV (quantity,value): from dir/clean.json the pieces merged and
// left, the gaps, and with its evaluation against the truth the wrong merges, the pieces missed
// and the fill errors; from dir/deform/deform.json each method's mean and max vertex error on the
// held-out frames. InputError naming the file when one is missing or not such a file.
std::string marker_summary_csv(const std::filesystem::path& dir);

// The pictures as DIR/marker_trails.png and DIR/marker_skin.png (atomic writes).
void save_marker_pictures(const MarkerPictures& pictures, const std::filesystem::path& dir);

// The report's section body (pictures in OUT/pictures, the marker stage in OUT/markers, links
// relative to OUT): the two figures and OUT/markers/markers.csv as a table.
std::string marker_pictures_html(const std::filesystem::path& out, const MarkerPictures& pictures);

}  // namespace bodymodel
