#include "assets/fit.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.h"

namespace bodymodel {

namespace {

void check_body(const AssetBinding& b, Eigen::Index rows, const char* what) {
  if (b.max_vertex_index() >= rows)
    throw InputError("asset '" + b.name + "' reads hm08 vertex " + std::to_string(b.max_vertex_index()) +
                     " but the " + what + " has " + std::to_string(rows) +
                     " rows (pass all 19158 hm08 vertices, helpers included)");
}

// The row's body vertices that carry weight (an exact row's padding indices carry 0).
template <typename F>
void for_each_reference(const AssetBinding& b, int i, F&& f) {
  for (int k = 0; k < 3; ++k)
    if (b.weights(i, k) != 0) f(b.vertices(i, k), b.weights(i, k));
}

}  // namespace

Eigen::Vector3d asset_offset_scale(const AssetBinding& binding, const Eigen::MatrixX3d& body_mm) {
  check_body(binding, body_mm.rows(), "body");
  if (!binding.scales) return Eigen::Vector3d::Constant(100.0);  // dm → mm
  Eigen::Vector3d s;
  for (int axis = 0; axis < 3; ++axis) {
    const AssetScale& sc = (*binding.scales)[axis];
    s[axis] = std::abs(body_mm(sc.a, axis) - body_mm(sc.b, axis)) / sc.denominator;
  }
  return s;
}

Eigen::MatrixX3d fit_asset(const AssetBinding& binding, const Eigen::MatrixX3d& body_mm) {
  const Eigen::Vector3d s = asset_offset_scale(binding, body_mm);
  Eigen::MatrixX3d X(binding.vertex_count(), 3);
  for (int i = 0; i < binding.vertex_count(); ++i) {
    Eigen::RowVector3d x = binding.offsets.row(i).cwiseProduct(s.transpose());
    for_each_reference(binding, i, [&](int v, double w) { x += w * body_mm.row(v); });
    X.row(i) = x;
  }
  return X;
}

SkinWeights asset_skin_weights(const AssetBinding& binding, const SkinWeights& body_weights) {
  check_body(binding, body_weights.rows(), "weight matrix");
  constexpr double kDrop = 1e-4;  // MakeHuman's WEIGHT_THRESHOLD (proxy.py)
  std::vector<Eigen::Triplet<double>> trip;
  Eigen::VectorXd acc = Eigen::VectorXd::Zero(body_weights.cols());
  std::vector<char> seen(body_weights.cols(), 0);  // not acc == 0: a negative mix can return to 0
  std::vector<int> touched;
  for (int i = 0; i < binding.vertex_count(); ++i) {
    touched.clear();
    for_each_reference(binding, i, [&](int v, double w) {
      for (SkinWeights::InnerIterator it(body_weights, v); it; ++it) {
        if (!seen[it.col()]) {
          seen[it.col()] = 1;
          touched.push_back(static_cast<int>(it.col()));
        }
        acc[it.col()] += w * it.value();
      }
    });
    double sum = 0;
    for (int c : touched) sum += acc[c] > kDrop ? acc[c] : 0;
    if (sum <= 0) {
      // Every product dropped: take the row of the vertex with the largest binding weight.
      int k_best = 0;
      for (int k = 1; k < 3; ++k) if (binding.weights(i, k) > binding.weights(i, k_best)) k_best = k;
      const int v = binding.vertices(i, k_best);
      for (SkinWeights::InnerIterator it(body_weights, v); it; ++it) trip.emplace_back(i, it.col(), it.value());
    } else {
      for (int c : touched)
        if (acc[c] > kDrop) trip.emplace_back(i, c, acc[c] / sum);
    }
    for (int c : touched) acc[c] = 0, seen[c] = 0;
  }
  SkinWeights W(binding.vertex_count(), body_weights.cols());
  W.setFromTriplets(trip.begin(), trip.end());
  return W;
}

Eigen::MatrixXd carry_through_binding(const AssetBinding& binding, const Eigen::MatrixXd& M) {
  check_body(binding, M.rows(), "attribute matrix");
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(binding.vertex_count(), M.cols());
  for (int i = 0; i < binding.vertex_count(); ++i)
    for_each_reference(binding, i, [&](int v, double w) { out.row(i) += w * M.row(v); });
  return out;
}

std::vector<char> hidden_body_vertices(const std::vector<const AssetBinding*>& assets, int vertex_count) {
  std::vector<char> hidden(std::max(0, vertex_count), 0);
  for (const AssetBinding* a : assets)
    for (int v : a->deleted_vertices)
      if (v < vertex_count) hidden[v] = 1;
  return hidden;
}

Eigen::MatrixX3i visible_faces(const Eigen::MatrixX3i& F, const std::vector<char>& hidden) {
  std::vector<int> keep;
  for (int f = 0; f < F.rows(); ++f) {
    bool show = true;
    for (int k = 0; k < 3; ++k) {
      const int v = F(f, k);
      if (v < 0 || v >= static_cast<int>(hidden.size()))
        throw InputError("visible_faces: face " + std::to_string(f) + " refers to vertex " +
                         std::to_string(v) + " outside the " + std::to_string(hidden.size()) + " of the mask");
      show = show && !hidden[v];
    }
    if (show) keep.push_back(f);
  }
  Eigen::MatrixX3i out(static_cast<Eigen::Index>(keep.size()), 3);
  for (size_t r = 0; r < keep.size(); ++r) out.row(r) = F.row(keep[r]);
  return out;
}

Asset load_asset(const std::filesystem::path& binding_file) {
  Asset a;
  a.file = binding_file;
  a.binding = read_asset_binding(binding_file);
  const std::filesystem::path dir = binding_file.parent_path();
  if (a.binding.obj_file.empty())
    throw InputError("'" + binding_file.string() + "': no obj_file line (the asset's mesh)");
  a.obj = read_obj_contents(dir / a.binding.obj_file);
  if (a.obj.V.rows() != a.binding.vertex_count())
    throw InputError("'" + (dir / a.binding.obj_file).string() + "' has " + std::to_string(a.obj.V.rows()) +
                     " vertices but its binding '" + binding_file.string() + "' has " +
                     std::to_string(a.binding.vertex_count()) + " rows");
  a.faces = triangulate(a.obj.polygons);
  if (!a.binding.material_file.empty()) a.material = read_asset_material(dir / a.binding.material_file);
  return a;
}

std::vector<std::filesystem::path> find_asset_files(const std::filesystem::path& folder) {
  std::vector<std::filesystem::path> out;
  std::error_code ec;
  if (!std::filesystem::is_directory(folder, ec))
    throw InputError("asset folder '" + folder.string() + "' does not exist");
  for (const auto& e : std::filesystem::recursive_directory_iterator(folder, ec)) {
    const auto ext = e.path().extension();
    if (e.is_regular_file() && (ext == ".mhclo" || ext == ".proxy")) out.push_back(e.path());
  }
  if (ec) throw InputError("cannot list '" + folder.string() + "': " + ec.message());
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace bodymodel
