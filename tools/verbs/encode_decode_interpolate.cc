// bodymodel encode mesh... [--template T] --out enc.npz
// bodymodel decode enc.npz [--template T] --out DIR/ [--format obj|ply]
// bodymodel interpolate a.ply b.ply [--template T] [--steps 5] [--vertex] --out DIR/
//
// The relative rotation encoding (encoding/relative_rotation_encoding.h) on the command line.
// An encoding file is a NumPy .npz, keys in encoding/encoding_file.h. `decode` names its meshes
// after the stored names only through unique_file_names (core/io/file_names.h) and writes them
// through a staging folder (tools/pipeline/output_folder.h): all or nothing, and an existing
// folder only with --force.
#include <fmt/format.h>

#include <cmath>
#include <filesystem>

#include "core/error.h"
#include "core/geometry.h"
#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "core/io/npz.h"
#include "core/io/file_names.h"
#include "encoding/encoding_file.h"
#include "encoding/relative_rotation_decoder.h"
#include "encoding/relative_rotation_encoding.h"
#include "tools/console.h"
#include "tools/pipeline/output_folder.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

constexpr const char* kLayout =
    "Relative rotation encoding (Hasler et al. 2009 sec. 3), 15 float64 per triangle f, "
    "triangle-major: [15f+3k .. 15f+3k+2] rotation vector (radians) of the relative rotation "
    "R_f^T R_g to the triangle g across edge k (F[f,k] -> F[f,(k+1)%3]); 0 for a boundary edge; "
    "[15f+9 .. 15f+14] stretch S_f entries xx xy xz yy yz zz. Rows of 'encodings' are relative "
    "to 'mean': stretch minus the mean's, rotation vector d with R = exp(mean) exp(d).";

Mesh read_checked(const fs::path& p) {
  Mesh m = read_mesh(p);
  if (m.V.rows() == 0 || m.F.rows() == 0)
    throw InputError(p.string() + ": expected a triangle mesh, found no vertices or faces");
  return m;
}

std::shared_ptr<const EncodingTemplate> make_template(const Mesh& m, const std::string& what) {
  try {
    return std::make_shared<const EncodingTemplate>(m.V, m.F);
  } catch (const InputError& e) {
    throw InputError(what + ": " + e.what());
  }
}

// ---- encode ---------------------------------------------------------------------------------

struct EncodeArgs {
  std::vector<std::string> meshes;
  std::string templ, out;
};

void run_encode(const EncodeArgs& a) {
  const fs::path tpath = a.templ.empty() ? fs::path(a.meshes.front()) : fs::path(a.templ);
  const Mesh t = read_checked(tpath);
  auto tmpl = make_template(t, tpath.string());
  // Checked before any work: `--out o/` is a folder, not a file name.
  std::error_code ec;
  if (fs::path(a.out).filename().empty() || fs::is_directory(a.out, ec))
    throw InputError("--out '" + a.out + "': it is a folder; expected the name of the .npz file to write");
  cli::ProgressBar bar("encode");
  std::vector<Eigen::VectorXd> absolute;
  std::vector<std::string> stems;
  for (size_t i = 0; i < a.meshes.size(); ++i) {
    const Mesh m = read_checked(a.meshes[i]);
    tmpl->check_vertices(m.V, a.meshes[i]);
    tmpl->check_faces(m.F, a.meshes[i]);
    try {
      absolute.push_back(encode_absolute(*tmpl, m.V));
    } catch (const InputError& e) {
      throw InputError(a.meshes[i] + ": " + e.what());
    }
    stems.push_back(fs::path(a.meshes[i]).stem().string());
    bar.update(static_cast<double>(i + 1) / a.meshes.size(), fs::path(a.meshes[i]).filename().string());
  }
  auto mean = EncodingMean::average(absolute);
  Eigen::MatrixXd rows(absolute.size(), tmpl->encoding_size());
  for (size_t i = 0; i < absolute.size(); ++i)
    rows.row(i) = relative_to(mean, absolute[i]).values.transpose();
  EncodingFile file;
  file.encodings = rows;
  file.mean = mean->values;
  file.template_vertices = tmpl->rest_vertices();
  file.template_faces = tmpl->faces();
  // The names decode gives the meshes: plain and distinct (body.obj and body.ply → body, body_2).
  file.names = unique_file_names(stems, "mesh");
  encoding_to_npz(file, kLayout).save(a.out);
  bar.finish(fmt::format("{} meshes, {} triangles, {} values each -> {}", absolute.size(),
                         tmpl->triangle_count(), tmpl->encoding_size(), a.out));
}

// ---- decode ---------------------------------------------------------------------------------

struct DecodeArgs {
  std::string input, templ, out, format;
  bool force = false;
};

void run_decode(const DecodeArgs& a) {
  std::string ext = a.format.empty() ? ".obj" : "." + a.format;
  if (ext != ".obj" && ext != ".ply") throw InputError("--format must be obj or ply, found " + a.format);
  // Every array is checked before anything is decoded or written.
  const EncodingFile file = parse_encoding_npz(Npz::load(a.input), a.input, !a.templ.empty());
  Mesh t;
  if (!a.templ.empty()) {
    t = read_checked(a.templ);
  } else {
    t.V = file.template_vertices;
    t.F = file.template_faces;
  }
  auto tmpl = make_template(t, a.templ.empty() ? a.input + ": 'template_vertices'/'template_faces'" : a.templ);
  if (file.template_faces.rows() > 0)
    tmpl->check_faces(file.template_faces, "--template " + a.templ + " (against " + a.input + ")");
  if (file.encodings.cols() != tmpl->encoding_size())
    throw InputError(fmt::format("{}: 'encodings' has {} columns, the template needs {} (15 per triangle)", a.input,
                                 file.encodings.cols(), tmpl->encoding_size()));
  for (size_t i = 0; i < file.names.size(); ++i)
    if (file.file_names[i] != file.names[i])
      cli::info(fmt::format("row {}: the stored name is not a plain file name or repeats an earlier one; writing "
                            "'{}{}'",
                            i, file.file_names[i], ext));
  auto mean = EncodingMean::from_values(file.mean);
  StagedFolder out(a.out, a.force);
  RelativeRotationDecoder decoder(tmpl);
  cli::ProgressBar bar("decode");
  double total_ms = 0;
  const Eigen::Index n = file.encodings.rows();
  auto item = [&](Eigen::Index i) { return fmt::format("row {} ('{}')", i, file.file_names[static_cast<size_t>(i)]); };
  for (Eigen::Index i = 0; i < n; ++i) {
    const Encoding e{file.encodings.row(i).transpose(), mean};
    Eigen::MatrixX3d V;
    try {
      V = decoder.decode(e);
    } catch (const InputError& err) {
      throw InputError(fmt::format("{}: 'encodings' {}: {}", a.input, item(i), err.what()));
    } catch (const NumericalError& err) {
      throw NumericalError(fmt::format("{}: 'encodings' {}: {}", a.input, item(i), err.what()));
    }
    if (!V.allFinite())
      throw NumericalError(fmt::format("{}: 'encodings' {} decoded to non-finite vertices", a.input, item(i)));
    total_ms += decoder.last_timing().total_ms;
    write_mesh(out / (file.file_names[static_cast<size_t>(i)] + ext), V, tmpl->faces());
    bar.update(static_cast<double>(i + 1) / n, file.file_names[static_cast<size_t>(i)]);
  }
  out.commit();
  bar.finish(fmt::format("{} meshes -> {} (decode {:.1f} ms per mesh)", n, a.out,
                         total_ms / std::max<Eigen::Index>(1, n)));
}

// ---- interpolate ----------------------------------------------------------------------------

struct InterpolateArgs {
  std::vector<std::string> meshes;  // exactly two
  std::string templ, out;
  int steps = 5;
  bool vertex = false, force = false;
};

void run_interpolate(const InterpolateArgs& a) {
  if (a.meshes.size() != 2)
    throw InputError(fmt::format("interpolate: expected two meshes, found {}", a.meshes.size()));
  if (a.steps < 2) throw InputError("--steps must be at least 2 (the two ends)");
  const Mesh A = read_checked(a.meshes[0]), B = read_checked(a.meshes[1]);
  const fs::path tpath = a.templ.empty() ? fs::path(a.meshes[0]) : fs::path(a.templ);
  const Mesh t = a.templ.empty() ? A : read_checked(tpath);
  auto tmpl = make_template(t, tpath.string());
  for (const auto& [m, name] : {std::pair<const Mesh&, const std::string&>{A, a.meshes[0]},
                                {B, a.meshes[1]}}) {
    tmpl->check_vertices(m.V, name);
    tmpl->check_faces(m.F, name);
  }
  StagedFolder out(a.out, a.force);
  std::string ext = fs::path(a.meshes[0]).extension().string();
  if (ext != ".ply" && ext != ".PLY") ext = ".obj";
  const std::string stem = a.vertex ? "vertex" : "rre";
  cli::ProgressBar bar(a.vertex ? "interpolate (vertex)" : "interpolate (RRE)");
  std::unique_ptr<RelativeRotationDecoder> decoder;
  EncodedSet set;
  if (!a.vertex) {
    set = encode_set(*tmpl, {A.V, B.V});
    decoder = std::make_unique<RelativeRotationDecoder>(tmpl);
  }
  for (int s = 0; s < a.steps; ++s) {
    const double u = static_cast<double>(s) / (a.steps - 1);
    Eigen::MatrixX3d V;
    if (a.vertex) {
      V = (1 - u) * A.V + u * B.V;
    } else {
      V = decoder->decode(interpolate(set.encodings[0], set.encodings[1], u));
      // Place the in-between on the straight path of the centroids and rotation-aligned to
      // the nearer end, so a sequence plays in place.
      const Eigen::MatrixX3d& ref = u < 0.5 ? A.V : B.V;
      V = apply(fit_rigid_motion(V, ref), V);
    }
    write_mesh(out / (fmt::format("{}_{:03d}", stem, s) + ext), V, tmpl->faces());
    bar.update(static_cast<double>(s + 1) / a.steps);
  }
  out.commit();
  bar.finish(fmt::format("{} meshes -> {}", a.steps, a.out));
}

}  // namespace
}  // namespace bodymodel

BODYMODEL_VERB(add_encoding_verbs) {
  using namespace bodymodel;
  {
    auto a = std::make_shared<EncodeArgs>();
    auto* cmd = app.add_subcommand(
        "encode",
        "Encode meshes (template topology) in the relative rotation encoding, relative to their "
        "component-wise mean; writes an .npz (keys: encodings, mean, template_vertices, "
        "template_faces, names, layout)");
    cmd->add_option("meshes", a->meshes, "meshes (.obj/.ply) with the template's vertices and faces")
        ->required()
        ->check(CLI::ExistingFile);
    cmd->add_option("--template", a->templ, "template mesh (rest shape); default: the first mesh")
        ->check(CLI::ExistingFile);
    cmd->add_option("--out", a->out, "output .npz")->required();
    cmd->callback([a] { run_encode(*a); });
  }
  {
    auto a = std::make_shared<DecodeArgs>();
    auto* cmd = app.add_subcommand(
        "decode",
        "Decode an encoding .npz (from `encode` or the model) into one mesh per row, named after "
        "the encoded inputs");
    cmd->add_option("encoding", a->input, "encoding .npz")->required()->check(CLI::ExistingFile);
    cmd->add_option("--template", a->templ,
                    "template mesh; default: the template stored in the .npz")
        ->check(CLI::ExistingFile);
    cmd->add_option("--out", a->out, "output folder (must not exist unless --force)")->required();
    cmd->add_option("--format", a->format, "obj (default) or ply");
    cmd->add_flag("--force", a->force, "Replace an existing output folder");
    cmd->callback([a] { run_decode(*a); });
  }
  {
    auto a = std::make_shared<InterpolateArgs>();
    auto* cmd = app.add_subcommand(
        "interpolate",
        "Interpolate between two meshes in the relative rotation encoding (limbs keep their "
        "length), or with --vertex linearly in vertex positions for comparison");
    cmd->add_option("meshes", a->meshes, "the two end meshes (same topology)")
        ->required()
        ->expected(2)
        ->check(CLI::ExistingFile);
    cmd->add_option("--template", a->templ, "template mesh (rest shape); default: the first mesh")
        ->check(CLI::ExistingFile);
    cmd->add_option("--steps", a->steps, "number of meshes written, ends included")
        ->capture_default_str();
    cmd->add_flag("--vertex", a->vertex, "naive vertex-position interpolation");
    cmd->add_option("--out", a->out, "output folder (rre_000.obj ... or vertex_000.obj ...; must not exist unless --force)")
        ->required();
    cmd->add_flag("--force", a->force, "Replace an existing output folder");
    cmd->callback([a] { run_interpolate(*a); });
  }
}
