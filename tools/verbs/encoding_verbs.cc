// bodymodel encode mesh... [--template T] --out enc.npz
// bodymodel decode enc.npz [--template T] --out DIR/ [--format obj|ply]
// bodymodel interpolate a.ply b.ply [--template T] [--steps 5] [--vertex] --out DIR/
//
// The relative rotation encoding (encoding/relative_rotation_encoding.h) on the command line.
// An encoding file is a NumPy .npz with these keys:
//   encodings          N by 15·#F float64, one row per input mesh, relative to `mean`
//                      (layout: encoding/relative_rotation_encoding.h)
//   mean               15·#F float64, the inputs' component-wise mean (absolute values)
//   template_vertices  #V by 3 float64, the template's rest vertices (input units, e.g. mm)
//   template_faces     #F by 3 int32, the template's triangles (0-based)
//   names              text: the input file stems, one per line (decoded meshes are named so)
//   layout             text: a one-paragraph description of the layout
#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <sstream>

#include "core/error.h"
#include "core/geometry.h"
#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "core/io/npz.h"
#include "encoding/relative_rotation_decoder.h"
#include "encoding/relative_rotation_encoding.h"
#include "tools/console.h"
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

std::string output_name(const fs::path& dir, const std::string& stem, const std::string& ext) {
  return (dir / (stem + ext)).string();
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
  cli::ProgressBar bar("encode");
  std::vector<Eigen::VectorXd> absolute;
  std::string names;
  for (size_t i = 0; i < a.meshes.size(); ++i) {
    const Mesh m = read_checked(a.meshes[i]);
    tmpl->check_vertices(m.V, a.meshes[i]);
    tmpl->check_faces(m.F, a.meshes[i]);
    try {
      absolute.push_back(encode_absolute(*tmpl, m.V));
    } catch (const InputError& e) {
      throw InputError(a.meshes[i] + ": " + e.what());
    }
    names += fs::path(a.meshes[i]).stem().string() + "\n";
    bar.update(static_cast<double>(i + 1) / a.meshes.size(), fs::path(a.meshes[i]).filename().string());
  }
  auto mean = EncodingMean::average(absolute);
  Eigen::MatrixXd rows(absolute.size(), tmpl->encoding_size());
  for (size_t i = 0; i < absolute.size(); ++i)
    rows.row(i) = relative_to(mean, absolute[i]).values.transpose();
  Npz npz;
  npz.put("encodings", rows);
  npz.put("mean", mean->values);
  npz.put("template_vertices", Eigen::MatrixXd(tmpl->rest_vertices()));
  npz.put("template_faces", Eigen::MatrixXi(tmpl->faces()));
  npz.put_text("names", names);
  npz.put_text("layout", kLayout);
  npz.save(a.out);
  bar.finish(fmt::format("{} meshes, {} triangles, {} values each -> {}", absolute.size(),
                         tmpl->triangle_count(), tmpl->encoding_size(), a.out));
}

// ---- decode ---------------------------------------------------------------------------------

struct DecodeArgs {
  std::string input, templ, out, format;
};

// "row 3 ('walk_02')": an encoding row and the mesh it decodes to.
std::string item_name(Eigen::Index row, const std::vector<std::string>& names) {
  return fmt::format("row {} ('{}')", row, names[static_cast<size_t>(row)]);
}

// The first non-finite value of `M` as "NaN at row r, column c", or "".
std::string first_non_finite(const Eigen::MatrixXd& M) {
  for (Eigen::Index r = 0; r < M.rows(); ++r)
    for (Eigen::Index c = 0; c < M.cols(); ++c)
      if (!std::isfinite(M(r, c)))
        return fmt::format("{} at row {}, column {}", std::isnan(M(r, c)) ? "NaN" : "infinity", r, c);
  return "";
}

void run_decode(const DecodeArgs& a) {
  const Npz npz = Npz::load(a.input);
  Mesh t;
  if (!a.templ.empty()) {
    t = read_checked(a.templ);
  } else {
    t.V = npz.matrix("template_vertices");
    t.F = npz.int_matrix("template_faces");
    if (const std::string bad = first_non_finite(t.V); !bad.empty())
      throw InputError(fmt::format("{}: 'template_vertices' holds {}, expected finite coordinates",
                                   a.input, bad));
  }
  auto tmpl = make_template(t, a.templ.empty() ? a.input + ": 'template_vertices'/'template_faces'" : a.templ);
  if (npz.has("template_faces")) {
    const Eigen::MatrixXi F = npz.int_matrix("template_faces");
    if (F.cols() != 3) throw InputError(a.input + ": template_faces must have 3 columns");
    tmpl->check_faces(Eigen::MatrixX3i(F), "--template " + a.templ + " (against " + a.input + ")");
  }
  const Eigen::MatrixXd rows = npz.matrix("encodings");
  if (rows.cols() != tmpl->encoding_size())
    throw InputError(fmt::format("{}: 'encodings' has {} columns, the template needs {} "
                                 "(15 per triangle)", a.input, rows.cols(), tmpl->encoding_size()));
  const Eigen::VectorXd mean_values = npz.vector("mean");
  if (mean_values.size() != tmpl->encoding_size())
    throw InputError(fmt::format("{}: 'mean' has {} values, expected {}", a.input,
                                 mean_values.size(), tmpl->encoding_size()));
  for (Eigen::Index k = 0; k < mean_values.size(); ++k)
    if (!std::isfinite(mean_values(k)))
      throw InputError(fmt::format("{}: 'mean' holds {} at value {} (triangle {}), expected finite values",
                                   a.input, std::isnan(mean_values(k)) ? "NaN" : "infinity", k, k / 15));
  auto mean = EncodingMean::from_values(mean_values);
  std::vector<std::string> names;
  if (npz.has("names")) {
    std::istringstream in(npz.text("names"));
    for (std::string line; std::getline(in, line);)
      if (!line.empty()) names.push_back(line);
  }
  while (names.size() < static_cast<size_t>(rows.rows()))
    names.push_back(fmt::format("decoded_{:03d}", names.size()));
  // Every row is checked before anything is written: a bad row names the file and the item.
  for (Eigen::Index i = 0; i < rows.rows(); ++i)
    for (Eigen::Index k = 0; k < rows.cols(); ++k)
      if (!std::isfinite(rows(i, k)))
        throw InputError(fmt::format("{}: 'encodings' {} holds {} at value {} (triangle {}), expected "
                                     "finite values",
                                     a.input, item_name(i, names), std::isnan(rows(i, k)) ? "NaN" : "infinity",
                                     k, k / 15));
  std::string ext = a.format.empty() ? ".obj" : "." + a.format;
  if (ext != ".obj" && ext != ".ply") throw InputError("--format must be obj or ply, found " + a.format);
  ensure_directory(a.out);
  RelativeRotationDecoder decoder(tmpl);
  cli::ProgressBar bar("decode");
  double total_ms = 0;
  for (Eigen::Index i = 0; i < rows.rows(); ++i) {
    const Encoding e{rows.row(i).transpose(), mean};
    Eigen::MatrixX3d V;
    try {
      V = decoder.decode(e);
    } catch (const InputError& err) {
      throw InputError(fmt::format("{}: 'encodings' {}: {}", a.input, item_name(i, names), err.what()));
    } catch (const NumericalError& err) {
      throw NumericalError(fmt::format("{}: 'encodings' {}: {}", a.input, item_name(i, names), err.what()));
    }
    if (!V.allFinite())
      throw NumericalError(fmt::format("{}: 'encodings' {} decoded to non-finite vertices", a.input,
                                       item_name(i, names)));
    total_ms += decoder.last_timing().total_ms;
    write_mesh(output_name(a.out, names[i], ext), V, tmpl->faces());
    bar.update(static_cast<double>(i + 1) / rows.rows(), names[i]);
  }
  bar.finish(fmt::format("{} meshes -> {} (decode {:.1f} ms per mesh)", rows.rows(), a.out,
                         total_ms / std::max<Eigen::Index>(1, rows.rows())));
}

// ---- interpolate ----------------------------------------------------------------------------

struct InterpolateArgs {
  std::vector<std::string> meshes;  // exactly two
  std::string templ, out;
  int steps = 5;
  bool vertex = false;
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
  ensure_directory(a.out);
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
    write_mesh(output_name(a.out, fmt::format("{}_{:03d}", stem, s), ext), V, tmpl->faces());
    bar.update(static_cast<double>(s + 1) / a.steps);
  }
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
    cmd->add_option("--out", a->out, "output folder")->required();
    cmd->add_option("--format", a->format, "obj (default) or ply");
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
    cmd->add_option("--out", a->out, "output folder (rre_000.obj ... or vertex_000.obj ...)")
        ->required();
    cmd->callback([a] { run_interpolate(*a); });
  }
}
