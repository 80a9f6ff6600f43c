#include "tools/pipeline/marker_pictures.h"

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"
#include "core/io/mesh_io.h"
#include "tools/report/html.h"

namespace bodymodel {

namespace fs = std::filesystem;

std::vector<std::vector<char>> filled_mask(const MarkerData& d, const std::vector<GapRecord>& gaps) {
  std::map<std::string, int> column;
  for (int i = 0; i < d.marker_count(); ++i) column[d.labels[i]] = i;
  std::vector<std::vector<char>> mask(d.frame_count(), std::vector<char>(d.marker_count(), 0));
  for (const GapRecord& g : gaps) {
    auto it = column.find(g.marker);
    if (it == column.end()) throw InputError("gap of marker '" + g.marker + "': no such marker in the capture");
    if (g.first < 0 || g.last < g.first || g.last >= d.frame_count())
      throw InputError(fmt::format("gap of marker '{}': frames {}-{} outside the capture's {} frames", g.marker, g.first,
                                   g.last, d.frame_count()));
    for (int t = g.first; t <= g.last; ++t) mask[t][it->second] = 1;
  }
  return mask;
}

std::vector<GapRecord> read_clean_gaps(const fs::path& report) {
  const nlohmann::json j = nlohmann::json::parse(read_text_file(report), nullptr, false);
  if (j.is_discarded() || !j.is_object() || !j.contains("gaps") || !j["gaps"].is_array())
    throw InputError("'" + report.string() + "': not a markers clean report with a \"gaps\" list");
  std::vector<GapRecord> gaps;
  for (const auto& g : j["gaps"]) {
    if (!g.is_object() || !g.contains("marker") || !g["marker"].is_string() || !g.contains("first_frame") ||
        !g["first_frame"].is_number_integer() || !g.contains("last_frame") || !g["last_frame"].is_number_integer())
      throw InputError(fmt::format("'{}': gap {} is not {{marker, first_frame, last_frame}}", report.string(), gaps.size()));
    gaps.push_back({g["marker"].get<std::string>(), g["first_frame"].get<int>(), g["last_frame"].get<int>()});
  }
  return gaps;
}

namespace {

// One ribbon segment p → q facing the camera (forward f), half width h, its ends extended by h so
// a marker at rest still shows as a square; appended with its own four corners.
void append_segment(const Eigen::Vector3d& p, const Eigen::Vector3d& q, const Eigen::Vector3d& f, double h,
                    const Eigen::Vector3d& colour, std::vector<Eigen::Vector3d>& V, std::vector<Eigen::Vector3i>& F,
                    std::vector<Eigen::Vector3d>& C, const Eigen::Vector3d& up) {
  Eigen::Vector3d u = (q - p) - (q - p).dot(f) * f;  // the segment in the picture's plane
  u = u.norm() > 1e-9 * h ? u.normalized() : up;
  const Eigen::Vector3d w = f.cross(u).normalized();
  const int b = static_cast<int>(V.size());
  const Eigen::Vector3d a = p - h * u, e = q + h * u, s = h * w;
  for (const Eigen::Vector3d& c : std::array<Eigen::Vector3d, 4>{a - s, a + s, e + s, e - s}) {
    V.push_back(c);
    C.push_back(colour);
  }
  F.emplace_back(b, b + 1, b + 2);
  F.emplace_back(b, b + 2, b + 3);
}

}  // namespace

Image marker_trails_picture(const MarkerData& d, const std::vector<std::vector<char>>& filled, int first, int count,
                            int width, int height, double width_mm, const Camera& camera) {
  if (count < 1 || first < 0 || first + count > d.frame_count() || static_cast<int>(filled.size()) != d.frame_count())
    throw InputError(fmt::format("marker trails: frames {}+{} outside the capture's {} (or a mask of another size)", first,
                                 count, d.frame_count()));
  const Eigen::Vector3d f = camera.forward.normalized(), up = camera.up.normalized();
  const double h = width_mm / 2;
  std::vector<Eigen::Vector3d> V, C;
  std::vector<Eigen::Vector3i> F;
  // Seen segments first; filled ones nudged towards the camera by a ribbon width.
  for (int pass = 0; pass < 2; ++pass)
    for (int m = 0; m < d.marker_count(); ++m)
      for (int t = first; t < first + count; ++t) {
        if (!d.present(t, m))
          throw InputError(fmt::format("marker trails: '{}' is missing at frame {} (give a cleaned capture)", d.labels[m], t));
        const int t1 = std::min(t + 1, first + count - 1);
        const bool is_filled = filled[t][m] || filled[t1][m];
        if (is_filled != (pass == 1)) continue;
        const Eigen::Vector3d lift = is_filled ? Eigen::Vector3d(-2 * h * f) : Eigen::Vector3d::Zero();
        append_segment(d.at(t, m) + lift, d.at(t1, m) + lift, f, is_filled ? 1.5 * h : h,
                       is_filled ? kTrailFilled : kTrailSeen, V, F, C, up);
      }
  Eigen::MatrixX3d VV(V.size(), 3), CC(C.size(), 3);
  Eigen::MatrixX3i FF(F.size(), 3);
  for (size_t i = 0; i < V.size(); ++i) VV.row(i) = V[i].transpose(), CC.row(i) = C[i].transpose();
  for (size_t i = 0; i < F.size(); ++i) FF.row(i) = F[i].transpose();
  return render_mesh(VV, FF, CC, width, height, camera);
}

Image skin_beside_truth_picture(const Eigen::MatrixX3d& truth, const Eigen::MatrixX3d& skin, const Eigen::MatrixX3i& F,
                                double mm_per_unit, double scale_mm, int cell_width, int height) {
  if (truth.rows() != skin.rows())
    throw InputError(fmt::format("skin beside truth: {} skin vertices, {} true ones (the error is per vertex)", skin.rows(),
                                 truth.rows()));
  const Eigen::VectorXd err = (skin - truth).rowwise().norm() * mm_per_unit;
  // One scale and floor for both: render_row frames the union of their (centred) boxes.
  const Image row = render_row(std::vector<Eigen::MatrixX3d>{truth, skin}, F,
                               {Eigen::MatrixX3d(), heat_colors(err, 0, scale_mm)}, cell_width, height);
  Image img(row.width, height + 24);
  img.paste(row, 0, 0);
  img.paste(heat_colorbar(cell_width - 40, 12), cell_width + 20, height + 6);
  return img;
}

namespace {

// The held-out frame where Park's skin is worst (errors.csv), among those with a park_FFFFF.obj.
void pick_held_out(const fs::path& deform, MarkerPictures& p) {
  const auto rows = read_csv_file(deform / "errors.csv");
  if (rows.empty()) throw InputError("'" + (deform / "errors.csv").string() + "' is empty");
  const auto& head = rows[0].fields;
  const auto col = std::find(head.begin(), head.end(), "park_mean_mm") - head.begin();
  if (col == static_cast<long>(head.size()) || head.size() < 2)
    throw InputError("'" + (deform / "errors.csv").string() + "' has no park_mean_mm column");
  std::error_code ec;
  for (size_t k = 1; k < rows.size(); ++k) {
    const auto& r = rows[k].fields;
    if (r.size() != head.size()) continue;
    const int frame = std::stoi(r[1]);
    const double e = std::stod(r[static_cast<size_t>(col)]);
    if (!fs::is_regular_file(deform / fmt::format("park_{:05d}.obj", frame), ec) || e <= p.park_mean_mm) continue;
    p.park_mean_mm = e;
    p.held_out_capture_frame = frame;
    p.held_out_mesh = std::stoi(r[0]);
  }
  if (p.held_out_capture_frame < 0)
    throw InputError("no held-out frame of '" + deform.string() + "' has its park_FFFFF.obj (run deform with --write-every)");
}

}  // namespace

MarkerPictures marker_pictures(const fs::path& dir, const std::vector<fs::path>& meshes, int frames_per_mesh,
                               double mm_per_unit) {
  MarkerPictures p;
  const MarkerData cleaned = read_markers(dir / "clean.trc");
  const std::vector<GapRecord> gaps = read_clean_gaps(dir / "clean.json");
  const auto mask = filled_mask(cleaned, gaps);
  p.frames = cleaned.frame_count();
  p.markers = cleaned.marker_count();
  p.gaps = static_cast<int>(gaps.size());
  for (const GapRecord& g : gaps) p.filled_samples += g.last - g.first + 1;
  // Two views of the same trails: from +x (the front of the Vlasic captures) and from +z.
  Camera front;
  front.forward = Eigen::Vector3d(-1, 0, 0);
  p.trails = Image(640, 520);
  p.trails.paste(marker_trails_picture(cleaned, mask, 0, p.frames, 320, 520, 6, front), 0, 0);
  p.trails.paste(marker_trails_picture(cleaned, mask, 0, p.frames, 320, 520), 320, 0);

  pick_held_out(dir / "deform", p);
  if (p.held_out_mesh < 0 || p.held_out_mesh >= static_cast<int>(meshes.size()) ||
      p.held_out_mesh * frames_per_mesh != p.held_out_capture_frame)
    throw InputError(fmt::format("held-out capture frame {} is not mesh {} of the {} given", p.held_out_capture_frame,
                                 p.held_out_mesh, meshes.size()));
  const Mesh truth = read_mesh(meshes[static_cast<size_t>(p.held_out_mesh)]);
  const Mesh skin = read_mesh(dir / "deform" / fmt::format("park_{:05d}.obj", p.held_out_capture_frame));
  p.skin = skin_beside_truth_picture(truth.V, skin.V, truth.F, mm_per_unit, 30, 260, 500);
  return p;
}

std::string marker_summary_csv(const fs::path& dir) {
  auto load = [](const fs::path& f) {
    nlohmann::json j = nlohmann::json::parse(read_text_file(f), nullptr, false);
    if (j.is_discarded() || !j.is_object()) throw InputError("'" + f.string() + "': not a JSON object");
    return j;
  };
  const nlohmann::json c = load(dir / "clean.json"), d = load(dir / "deform" / "deform.json");
  std::string csv = "quantity,value\n";
  auto row = [&](const std::string& name, const nlohmann::json& v) {
    csv += csv_row({name, v.is_number_float() ? fmt::format("{:.2f}", v.get<double>()) : v.dump()}) + "\n";
  };
  try {
    row("markers", c.at("markers"));
    row("pieces merged", c.at("merged"));
    row("pieces left", c.at("unmerged").size());
    row("gaps found after merging", c.at("gaps_found"));
    row("samples filled", c.at("samples_missing"));
    if (c.contains("evaluation")) {
      const auto& e = c["evaluation"];
      row("wrong merges (truth)", e.at("wrong_merges"));
      row("pieces of a marker left (truth)", e.at("missed_pieces"));
      row("median fill error (mm)", e.at("median_fill_mm"));
      row("median fill error, holes between samples (mm)", e.at("median_interior_fill_mm"));
      row("cubic spline on the same holes (mm)", e.at("median_spline_mm"));
    }
    row("held-out frames", d.at("test_frames").size());
    for (const auto& [method, e] : d.at("errors").items())
      csv += csv_row({method + " mean / max vertex error (mm)",
                      fmt::format("{:.2f} / {:.1f}", e.at("mean_mm").get<double>(), e.at("max_mm").get<double>())}) + "\n";
  } catch (const nlohmann::json::exception& e) {
    throw InputError("'" + dir.string() + "': clean.json or deform/deform.json lacks a figure: " + e.what());
  }
  return csv;
}

void save_marker_pictures(const MarkerPictures& p, const fs::path& dir) {
  p.trails.save_png(dir / "marker_trails.png");
  p.skin.save_png(dir / "marker_skin.png");
}

std::string marker_pictures_html(const fs::path& out, const MarkerPictures& p) {
  std::string b = html_figure(
      out / "pictures" / "marker_trails.png", "pictures/marker_trails.png",
      fmt::format("Trails of the {} cleaned markers over the {} frames (120 Hz) of the clip, from the front and the side: measured or "
                  "merged samples in blue, the {} samples of the {} gaps the cleaning filled in orange.",
                  p.markers, p.frames, p.filled_samples, p.gaps));
  b += html_figure(out / "pictures" / "marker_skin.png", "pictures/marker_skin.png",
                   fmt::format("Held-out capture frame {} (mesh {}, the one where the skin is worst): the true mesh (grey) "
                               "and the mesh driven by the cleaned markers (Park and Hodgins: parts, quadratic, RBF), "
                               "coloured by the distance to the truth, blue 0 → red ≥ 30 mm; mean {:.1f} mm.",
                               p.held_out_capture_frame, p.held_out_mesh, p.park_mean_mm));
  b += html_table_from_csv(out / "markers" / "markers.csv", "markers/markers.csv");
  return b;
}

}  // namespace bodymodel
