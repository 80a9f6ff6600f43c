#include "model/model_shape_space.h"

#include <fmt/format.h>

#include <chrono>
#include <cmath>

#include "core/error.h"
#include "core/geometry.h"
#include "core/makehuman.h"
#include "encoding/relative_rotation_decoder.h"

namespace bodymodel {

namespace {

Eigen::VectorXd flatten(const Eigen::MatrixX3d& V) {
  Eigen::VectorXd x(3 * V.rows());
  for (Eigen::Index i = 0; i < V.rows(); ++i) x.segment<3>(3 * i) = V.row(i).transpose();
  return x;
}

}  // namespace

VertexShapeSpace model_shape_space(const BodyModel& model, const ModelShapeSpaceOptions& o,
                                   ModelShapeSpaceSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  const int nv = MakeHuman::kBodyVertexCount;
  if (!model.tmpl || model.tmpl->rest_vertices().rows() != nv)
    throw InputError(fmt::format("model: {} vertices, the registration template has {} (MakeHuman's body): "
                                 "only a model built from registrations can be the shape space",
                                 model.tmpl ? model.tmpl->rest_vertices().rows() : 0, nv));
  const Pca& pca = model.shape.pca;
  if (pca.component_count() < 1) throw InputError("model: its shape model has no components");
  if (o.components == 0 || o.components < -1)
    throw InputError(fmt::format("model components must be ≥ 1 or -1 (all), got {}", o.components));
  if (!(o.step_sd > 0) || !(o.error_at_sd > 0)) throw InputError("model shape space: steps must be positive");
  if (o.frame.rows() != 0 && o.frame.rows() != nv) throw InputError("model shape space: the frame is not the body's");
  const int K = o.components < 0 ? pca.component_count() : std::min(o.components, pca.component_count());

  const RelativeRotationDecoder decoder(model.tmpl);
  ModelShapeSpaceSummary sum;
  sum.components = K;
  auto decode_at = [&](int k, double sd) {  // k < 0: the mean
    Eigen::VectorXd x = pca.mean;
    if (k >= 0) x += sd * std::sqrt(std::max(0.0, pca.eigenvalues[k])) * pca.basis.col(k);
    ++sum.decodes;
    return decoder.decode(model.encoding_of(std::move(x)));
  };
  VertexShapeSpace s;
  const Eigen::MatrixX3d mean_model_frame = decode_at(-1, 0);
  RigidMotion place;
  if (o.frame.rows() == nv) place = fit_rigid_motion(mean_model_frame, o.frame);
  s.mean = apply(place, mean_model_frame);
  s.offsets.resize(3 * nv, K);
  if (o.second_order) s.curvature.resize(3 * nv, K);
  for (int k = 0; k < K; ++k) {
    // Every decode is aligned to the model's rest shape by the decoder: differences of decodes are
    // in the model's frame, rotated into the space's.
    const Eigen::MatrixX3d plus = decode_at(k, o.step_sd), minus = decode_at(k, -o.step_sd);
    s.offsets.col(k) = flatten(((plus - minus) / (2 * o.step_sd)) * place.R.transpose());
    if (o.second_order)
      s.curvature.col(k) =
          flatten(((plus + minus - 2 * mean_model_frame) / (o.step_sd * o.step_sd)) * place.R.transpose());
  }
  s.source = fmt::format("model shape space, {} of {} components, {} at its mean", K, pca.component_count(),
                         o.second_order ? "second order" : "linearised");
  if (o.measure_error) {
    VertexShapeSpace linear = s;
    linear.curvature.resize(0, 0);
    // Vertex distances of the exact decode at c from the space's body of c (rigidly aligned).
    auto error = [&](const VertexShapeSpace& space, const Eigen::MatrixX3d& exact, const Eigen::VectorXd& c) {
      const Eigen::MatrixX3d L = vertex_space_body_vertices(space, c);
      return Eigen::VectorXd((apply(fit_rigid_motion(exact, L), exact) - L).rowwise().norm());
    };
    for (int k = 0; k < K; ++k)
      for (double sign : {1.0, -1.0}) {
        const Eigen::MatrixX3d exact = decode_at(k, sign * o.error_at_sd);
        Eigen::VectorXd c = Eigen::VectorXd::Zero(K);
        c[k] = sign * o.error_at_sd;
        const Eigen::VectorXd e = error(s, exact, c), el = error(linear, exact, c);
        sum.max_displacement_mm =
            std::max(sum.max_displacement_mm, (vertex_space_body_vertices(s, c) - s.mean).rowwise().norm().maxCoeff());
        sum.mean_error_mm += e.mean() / (2 * K), sum.mean_error_linear_mm += el.mean() / (2 * K);
        sum.max_error_linear_mm = std::max(sum.max_error_linear_mm, el.maxCoeff());
        if (e.maxCoeff() > sum.max_error_mm) sum.max_error_mm = e.maxCoeff(), sum.worst_component = k;
      }
  }
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (summary) *summary = sum;
  return s;
}

}  // namespace bodymodel
