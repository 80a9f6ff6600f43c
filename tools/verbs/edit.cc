// bodymodel edit model.npz --in body.ply --handle VERTEX:dx,dy,dz ... --out out.obj
#include <fmt/format.h>

#include "core/body_size.h"
#include "core/io/mesh_io.h"
#include "model/pose_edit.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"

namespace bodymodel {
namespace {

struct EditArgs {
  std::string model, in, out;
  std::vector<std::string> handles;
  int iterations = 10;
};

VertexHandle parse_handle(const std::string& s) {
  auto colon = s.find(':');
  if (colon == std::string::npos)
    throw InputError(fmt::format("--handle expects VERTEX:dx,dy,dz (mm), got '{}'", s));
  VertexHandle h;
  double v = model_cli::parse_number(s.substr(0, colon), "--handle vertex");
  if (v != std::floor(v)) throw InputError(fmt::format("--handle: vertex '{}' is not an index", s.substr(0, colon)));
  h.vertex = static_cast<int>(v);
  std::string rest = s.substr(colon + 1);
  for (int c = 0; c < 3; ++c) {
    auto comma = rest.find(',');
    if ((c < 2) != (comma != std::string::npos))
      throw InputError(fmt::format("--handle expects VERTEX:dx,dy,dz (mm), got '{}'", s));
    h.offset(c) = model_cli::parse_number(rest.substr(0, comma), "--handle offset");
    rest = comma == std::string::npos ? "" : rest.substr(comma + 1);
  }
  return h;
}

}  // namespace

BODYMODEL_VERB(add_model_edit_verb) {
  auto a = std::make_shared<EditArgs>();
  auto* cmd = app.add_subcommand(
      "edit",
      "Edit a body by dragging vertices (§5.3): positional constraints in the decoder, projection\n"
      "back into the shape model, repeated; the result stays a plausible body.");
  cmd->add_option("model", a->model, "Model (.npz from `bodymodel build`)")->required();
  cmd->add_option("--in", a->in, "Body mesh with the model's topology (OBJ/PLY, mm)")->required();
  cmd->add_option("--handle", a->handles, "VERTEX:dx,dy,dz displacement in mm, repeatable")->required();
  cmd->add_option("--iterations", a->iterations, "Project-and-solve iterations")->capture_default_str();
  cmd->add_option("--out", a->out, "Output mesh (OBJ/PLY)")->required();
  cmd->callback([a] {
    std::vector<VertexHandle> handles;
    for (auto& h : a->handles) handles.push_back(parse_handle(h));
    BodyModel model = model_cli::load_model_for_cli(a->model);
    Mesh body = read_mesh(a->in);
    model.check_topology(body.V, body.F, "'" + a->in + "'");
    check_body_size(body.V, "'" + a->in + "'");
    RelativeRotationDecoder decoder(model.tmpl);
    EditOptions o;
    o.iterations = a->iterations;
    EditSummary s;
    Eigen::MatrixX3d out = edit_with_handles(model, decoder, body.V, handles, o, &s);
    write_mesh(a->out, out, body.F);
    fmt::print("{} iterations; handle error max {:.2f} mm, mean {:.2f} mm\n", s.iterations, s.max_handle_error_mm,
               s.mean_handle_error_mm);
    cli::info("wrote " + a->out);
  });
}

}  // namespace bodymodel
