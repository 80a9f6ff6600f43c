// bodymodel render mesh... --out picture.png : meshes (side by side) or a scan as a PNG.
#include <fmt/format.h>

#include "core/error.h"
#include "core/io/mesh_io.h"
#include "tools/render/render.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {
struct RenderArgs {
  std::vector<std::string> inputs;
  std::string out;
  std::string view = "front";
  int width = 360, height = 720;
  bool points = false;
};

Camera camera_for(const std::string& view) {
  Camera c;
  if (view == "front") c.forward = {0, 0, -1};
  else if (view == "back") c.forward = {0, 0, 1};
  else if (view == "side") c.forward = {-1, 0, 0};
  else if (view == "top") { c.forward = {0, -1, 0}; c.up = {0, 0, -1}; }
  else throw InputError("--view must be front, back, side or top (got '" + view + "')");
  return c;
}
}  // namespace

BODYMODEL_VERB(add_render_verb) {
  auto a = std::make_shared<RenderArgs>();
  auto* cmd = app.add_subcommand(
      "render", "Render meshes side by side (or point clouds with --points) to a PNG, headless.");
  cmd->add_option("inputs", a->inputs, "Meshes (OBJ/PLY) or, with --points, point clouds (PLY)")
      ->required();
  cmd->add_option("--out", a->out, "PNG file to write")->required();
  cmd->add_option("--view", a->view, "front, back, side or top")->capture_default_str();
  cmd->add_option("--width", a->width, "Width of each picture cell, pixels")->capture_default_str();
  cmd->add_option("--height", a->height, "Height, pixels")->capture_default_str();
  cmd->add_flag("--points", a->points, "Inputs are point clouds (scans)");
  cmd->callback([a] {
    if (a->width < 16 || a->height < 16 || a->width > 8192 || a->height > 8192)
      throw InputError("--width and --height must be between 16 and 8192 pixels");
    Camera cam = camera_for(a->view);
    if (a->points) {
      Image row(a->width * int(a->inputs.size()), a->height);
      for (size_t i = 0; i < a->inputs.size(); ++i) {
        PointCloud pc = read_point_cloud(a->inputs[i]);
        row.paste(render_points(pc.P, pc.N, a->width, a->height, cam), int(i) * a->width, 0);
      }
      row.save_png(a->out);
    } else {
      std::vector<Eigen::MatrixX3d> meshes;
      Eigen::MatrixX3i F;
      Image row(a->width * int(a->inputs.size()), a->height);
      for (size_t i = 0; i < a->inputs.size(); ++i) {
        Mesh m = read_mesh(a->inputs[i]);
        meshes.push_back(m.V);
        if (i == 0) F = m.F;
        else if (m.F != F) {
          // Different topologies: render separately (no common scale).
          meshes.clear();
          break;
        }
      }
      if (!meshes.empty()) {
        render_row(meshes, F, {}, a->width, a->height, cam).save_png(a->out);
      } else {
        for (size_t i = 0; i < a->inputs.size(); ++i) {
          Mesh m = read_mesh(a->inputs[i]);
          row.paste(render_mesh(m.V, m.F, {}, a->width, a->height, cam), int(i) * a->width, 0);
        }
        row.save_png(a->out);
      }
    }
    fmt::print("wrote {}\n", a->out);
  });
}

}  // namespace bodymodel
