// Fitting the model to a mesh through the decoder (model/fit.h).
#include <gtest/gtest.h>

#include <random>

#include "core/error.h"
#include "model/fit.h"
#include "model_test_util.h"

namespace bodymodel {
namespace {

Eigen::VectorXd random_coefficients(const Pca& pca, int K, double sigmas, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0, 1);
  Eigen::VectorXd c(K);
  for (int k = 0; k < K; ++k) c(k) = sigmas * std::sqrt(pca.eigenvalues(k)) * n(rng);
  return c;
}

// The analytic Jacobian of the decoded vertices (rotation solve, closest rotation, Poisson)
// against central finite differences.
TEST(ModelFit, JacobianMatchesFiniteDifferences) {
  auto model = testing::shape_test_model();
  ModelFitter fitter(model->tmpl, model->mean, model->shape.pca);
  const int K = 6;
  const Eigen::VectorXd c = random_coefficients(model->shape.pca, K, 1.5, 3);
  Eigen::MatrixXd J;
  fitter.evaluate(c, &J);
  ASSERT_EQ(J.rows(), 3 * model->tmpl->vertex_count());
  ASSERT_EQ(J.cols(), K);
  for (int k = 0; k < K; ++k) {
    const double h = 1e-4 * std::sqrt(model->shape.pca.eigenvalues(k));
    Eigen::VectorXd cp = c, cm = c;
    cp(k) += h;
    cm(k) -= h;
    const Eigen::MatrixX3d d = (fitter.evaluate(cp) - fitter.evaluate(cm)) / (2 * h);
    Eigen::VectorXd fd(J.rows());
    for (int v = 0; v < d.rows(); ++v) fd.segment<3>(3 * v) = d.row(v).transpose();
    const double rel = (J.col(k) - fd).norm() / fd.norm();
    EXPECT_LT(rel, 1e-5) << "component " << k << ": |J − FD| / |FD| = " << rel;
  }
}

// The block solver (panels of four coefficients, the last one partial at K = 7) gives the
// decode and the Jacobian of the CHOLMOD reference path to rounding.
TEST(ModelFit, BlockSolverMatchesCholmodReference) {
  auto model = testing::shape_test_model();
  ModelFitter fitter(model->tmpl, model->mean, model->shape.pca);
  const int K = std::min(7, model->shape.pca.component_count());
  const Eigen::VectorXd c = random_coefficients(model->shape.pca, K, 1.5, 5);
  Eigen::MatrixXd J, Jref;
  const Eigen::MatrixX3d V = fitter.evaluate(c, &J), Vref = fitter.evaluate(c, &Jref, true);
  ASSERT_EQ(J.cols(), K);
  EXPECT_LT((V - Vref).cwiseAbs().maxCoeff(), 1e-9 * Vref.cwiseAbs().maxCoeff());
  for (int k = 0; k < K; ++k)
    EXPECT_LT((J.col(k) - Jref.col(k)).norm(), 1e-9 * Jref.col(k).norm()) << "component " << k;
}

// A body decoded from known coefficients, moved rigidly, is fitted back: the fitted body lies
// on it to ≤ 0.1 mm and the decoded coefficients agree to ≤ 0.1 mm.
TEST(ModelFit, RecoversKnownCoefficients) {
  auto model = testing::shape_test_model();
  const Pca& pca = model->shape.pca;
  ModelFitter fitter(model->tmpl, model->mean, pca);
  const int K = pca.component_count();
  const Eigen::VectorXd truth = random_coefficients(pca, K, 1.0, 7);
  RigidMotion move;
  move.R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, 1, 0.3).normalized()).toRotationMatrix();
  move.t = Eigen::Vector3d(120, -40, 900);
  const Eigen::MatrixX3d target = apply(move, fitter.evaluate(truth));
  ModelFit fit = fitter.fit(target);
  EXPECT_LT(fit.summary.max_mm, 0.1) << fit.summary.report();
  const Eigen::MatrixX3d a = fitter.evaluate(truth), b = fitter.evaluate(fit.coefficients);
  const double coefficient_mm = (apply(fit_rigid_motion(b, a), b) - a).rowwise().norm().maxCoeff();
  EXPECT_LT(coefficient_mm, 0.1);
  // The projection start is not the answer (a model sample has holonomy: its re-encoding is not
  // the sample), so the fit has work to do.
  EXPECT_GT(fit.summary.start_mean_mm, 10 * fit.summary.mean_mm) << fit.summary.report();
  std::printf("%s\n", fit.summary.report().c_str());
}

// A fit says whether it converged: on a body the model made, a normal run stops on its own
// tolerances; one or no iterations stop at the cap and say so (not converged, with the reason).
TEST(ModelFit, SaysWhetherItConverged) {
  auto model = testing::shape_test_model();
  const Pca& pca = model->shape.pca;
  ModelFitter fitter(model->tmpl, model->mean, pca);
  const Eigen::MatrixX3d target = fitter.evaluate(random_coefficients(pca, pca.component_count(), 1.0, 11));
  const ModelFit normal = fitter.fit(target);
  EXPECT_TRUE(normal.summary.converged) << normal.summary.report();
  EXPECT_LT(normal.summary.iterations, ModelFitOptions().max_iterations) << normal.summary.report();
  EXPECT_NE(normal.summary.report().find("; converged ("), std::string::npos) << normal.summary.report();
  for (int cont : {0, 16}) {
    ModelFitOptions tiny;
    tiny.max_iterations = 1;
    tiny.continuation_components = cont;
    const ModelFit capped = fitter.fit(target, tiny);
    EXPECT_FALSE(capped.summary.converged) << capped.summary.report();
    EXPECT_EQ(capped.summary.iterations, 1);
    EXPECT_NE(capped.summary.stop_reason.find("iteration"), std::string::npos) << capped.summary.stop_reason;
    EXPECT_NE(capped.summary.report().find("NOT CONVERGED"), std::string::npos) << capped.summary.report();
    // The capped fit is not yet at the answer the normal run reaches.
    EXPECT_GT(capped.summary.mean_mm, 2 * normal.summary.mean_mm) << capped.summary.report();
  }
  ModelFitOptions none;
  none.max_iterations = 0;
  const ModelFit start = fitter.fit(target, none);
  EXPECT_FALSE(start.summary.converged);
  EXPECT_NE(start.summary.stop_reason.find("no iterations"), std::string::npos) << start.summary.stop_reason;
}

// try_training_starts: a body near training sample 7 (its coefficients plus a small random
// change), moved rigidly, is fitted from the mean body with a tight iteration cap. The mean
// start stops at the cap unconverged; with the training starts the fit starts at sample 7 (the
// known nearest: the change is small next to the distances between subjects) and converges
// within the same cap onto the body.
TEST(ModelFit, TrainingStartConvergesWhereTheMeanStartStops) {
  auto model = testing::shape_test_model();
  const Pca& pca = model->shape.pca;
  ModelFitter fitter(model->tmpl, model->mean, pca);
  const int s = 7;
  ASSERT_GT(pca.coefficients.rows(), s);
  const Eigen::VectorXd truth =
      Eigen::VectorXd(pca.coefficients.row(s).transpose()) + random_coefficients(pca, pca.component_count(), 0.02, 13);
  RigidMotion move;
  move.R = Eigen::AngleAxisd(-0.4, Eigen::Vector3d(1, 0.5, 0).normalized()).toRotationMatrix();
  move.t = Eigen::Vector3d(-300, 80, 50);
  const Eigen::MatrixX3d target = apply(move, fitter.evaluate(truth));
  ModelFitOptions from_mean;
  from_mean.start_from_projection = false;
  from_mean.max_iterations = 5;
  from_mean.continuation_components = 0;
  ModelFitOptions nearest = from_mean;
  nearest.try_training_starts = true;
  const ModelFit a = fitter.fit(target, from_mean), b = fitter.fit(target, nearest);
  std::printf("mean start: %s\ntraining start: %s\n", a.summary.report().c_str(), b.summary.report().c_str());
  EXPECT_EQ(a.summary.start_sample, -1);
  EXPECT_FALSE(a.summary.converged) << a.summary.report();
  EXPECT_EQ(b.summary.start_sample, s) << b.summary.report();
  EXPECT_NE(b.summary.report().find("at training sample 7"), std::string::npos) << b.summary.report();
  EXPECT_LT(b.summary.start_mean_mm, a.summary.start_mean_mm / 3) << b.summary.report();
  EXPECT_TRUE(b.summary.converged) << b.summary.report();
  EXPECT_LT(b.summary.max_mm, 0.1) << b.summary.report();
  EXPECT_GT(a.summary.mean_mm, 10 * b.summary.mean_mm) << a.summary.report();
  // Each training sample costs one decode: the candidates are counted.
  EXPECT_GE(b.summary.evaluations, a.summary.evaluations + pca.coefficients.rows());
}

TEST(ModelFit, RejectsBadInput) {
  auto model = testing::shape_test_model();
  ModelFitter fitter(model->tmpl, model->mean, model->shape.pca);
  const Eigen::MatrixX3d V = model->tmpl->rest_vertices();
  ModelFitOptions o;
  o.components = model->shape.pca.component_count() + 1;
  try {
    fitter.fit(V, o);
    FAIL() << "K larger than the model accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("components requested, the model has"), std::string::npos) << e.what();
  }
  EXPECT_THROW(fitter.fit(V.topRows(100)), InputError);
  ModelFitOptions bad_coarse;
  bad_coarse.continuation_iterations = -1;
  EXPECT_THROW(fitter.fit(V, bad_coarse), InputError);
}

}  // namespace
}  // namespace bodymodel
