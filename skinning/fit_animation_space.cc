#include "skinning/fit_animation_space.h"

#include <chrono>
#include <sstream>

#include <Eigen/Cholesky>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "skinning/fit_lbs.h"

namespace bodymodel {

std::string AnimationSpaceFitSummary::brief() const {
  std::ostringstream s;
  s << "AS fit: " << vertices << " vertices, " << poses << " poses, ≤" << max_influences
    << " influences; residual RMS " << rms_residual << ", max " << max_residual << "; " << seconds
    << " s";
  return s.str();
}

SkinningRig fit_animation_space(const SkinningExamples& ex, const SkinningRig* base_lbs,
                                const AnimationSpaceFitOptions& options,
                                AnimationSpaceFitSummary* summary,
                                const ProgressCallback& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  validate_examples(ex, false);
  if (!(options.ridge >= 0)) throw InputError("animation space: ridge must be ≥ 0");
  const SkinningRig lbs = base_lbs_rig(ex, base_lbs, options.max_influences, "animation space");
  const Eigen::Index n = ex.rest.rows(), K = lbs.influences.cols();
  const int P = ex.pose_count();
  SkinningRig rig;
  rig.method = SkinningMethod::animation_space;
  rig.bone_count = lbs.bone_count;
  rig.rest = ex.rest;
  rig.influences = lbs.influences;
  rig.coefficients = Eigen::MatrixXd::Zero(n, 4 * K);
  const Eigen::Index chunk = std::max<Eigen::Index>(1024, n / 20);
  for (Eigen::Index start = 0; start < n; start += chunk) {
    report_progress(progress, double(start) / n, "Animation Space weights");
    const Eigen::Index stop = std::min(n, start + chunk);
    tbb::parallel_for(tbb::blocked_range<Eigen::Index>(start, stop, 64), [&](const auto& r) {
      for (Eigen::Index i = r.begin(); i < r.end(); ++i) {
        std::vector<Eigen::Index> slots;
        for (Eigen::Index k = 0; k < K; ++k)
          if (lbs.influences(i, k) >= 0) slots.push_back(k);
        const auto m = static_cast<Eigen::Index>(slots.size());
        const Eigen::Vector4d v(ex.rest(i, 0), ex.rest(i, 1), ex.rest(i, 2), 1.0);
        Eigen::MatrixXd A(3 * P, 4 * m);
        Eigen::VectorXd b(3 * P), prior(4 * m);
        for (Eigen::Index s = 0; s < m; ++s) {
          const Eigen::Index k = slots[static_cast<size_t>(s)];
          prior.segment<4>(4 * s) = lbs.coefficients(i, k) * v;
          for (int p = 0; p < P; ++p)
            A.block<3, 4>(3 * p, 4 * s) =
                ex.pose_weight(p) *
                ex.transforms[static_cast<size_t>(p)][static_cast<size_t>(lbs.influences(i, k))].affine();
        }
        for (int p = 0; p < P; ++p)
          b.segment<3>(3 * p) = ex.pose_weight(p) * ex.poses[static_cast<size_t>(p)].row(i).transpose();
        if (!options.prior_from_lbs) prior.setZero();
        Eigen::MatrixXd H = A.transpose() * A;
        const double lambda = options.ridge * H.trace() / double(4 * m) + 1e-14 * H.trace();
        H.diagonal().array() += lambda;
        const Eigen::VectorXd x = H.ldlt().solve(A.transpose() * b + lambda * prior);
        for (Eigen::Index s = 0; s < m; ++s)
          rig.coefficients.row(i).segment<4>(4 * slots[static_cast<size_t>(s)]) =
              x.segment<4>(4 * s).transpose();
      }
    });
  }
  report_progress(progress, 1.0, "Animation Space weights");
  if (!rig.coefficients.allFinite())
    throw NumericalError("animation space: the ridge solve produced non-finite weights");
  if (summary) {
    summary->vertices = static_cast<int>(n);
    summary->poses = P;
    summary->max_influences = static_cast<int>(K);
    summary->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    rig_residuals(rig, ex, &summary->rms_residual, &summary->max_residual);
  }
  return rig;
}

}  // namespace bodymodel
