// The part-wise pose model (model/part_pca.h).
#include <gtest/gtest.h>

#include "core/error.h"
#include "model/part_pca.h"
#include "model_test_util.h"

namespace bodymodel {
namespace {

// One part is the global PCA again (same span, same variances); four parts give orthonormal
// components each confined to one part, at least as many as the global PCA's, ordered by
// variance, that reproduce every training sample's encoding.
TEST(PartPca, OnePartIsTheGlobalPcaAndPartsReproduceTheSamples) {
  auto model = testing::shape_test_model();
  const Pca& g = model->shape.pca;
  const int nf = model->tmpl->triangle_count();
  const Pca one = part_wise_pca(g, std::vector<int>(nf, 0));
  ASSERT_EQ(one.component_count(), g.component_count());
  EXPECT_LT((one.eigenvalues - g.eigenvalues).cwiseAbs().maxCoeff(), 1e-9 * g.eigenvalues(0));
  EXPECT_LT((one.basis * (one.basis.transpose() * g.basis) - g.basis).cwiseAbs().maxCoeff(), 1e-9);

  const std::vector<int> part = spatial_triangle_parts(*model->tmpl, 4);
  ASSERT_EQ(static_cast<int>(part.size()), nf);
  std::vector<int> count(4, 0);
  for (int p : part) {
    ASSERT_GE(p, 0);
    ASSERT_LT(p, 4);
    ++count[p];
  }
  for (int c : count) EXPECT_GT(c, nf / 20) << "a part with " << c << " triangles";
  EXPECT_EQ(part, spatial_triangle_parts(*model->tmpl, 4));  // deterministic
  const Pca pp = part_wise_pca(g, part);
  EXPECT_GE(pp.component_count(), g.component_count());
  EXPECT_LE(pp.component_count(), 4 * static_cast<int>(g.coefficients.rows() - 1));
  const int K = pp.component_count();
  EXPECT_LT((pp.basis.transpose() * pp.basis - Eigen::MatrixXd::Identity(K, K)).cwiseAbs().maxCoeff(), 1e-9);
  for (int k = 0; k + 1 < K; ++k) EXPECT_GE(pp.eigenvalues(k), pp.eigenvalues(k + 1));
  for (int k = 0; k < K; ++k) {  // each column lives in one part
    std::vector<double> norm(4, 0.0);
    for (int f = 0; f < nf; ++f) norm[part[f]] += pp.basis.col(k).segment<15>(15 * f).squaredNorm();
    EXPECT_NEAR(*std::max_element(norm.begin(), norm.end()), 1.0, 1e-9) << "component " << k;
  }
  const Eigen::MatrixXd X = g.basis * g.coefficients.transpose();
  const Eigen::MatrixXd Xp = pp.basis * pp.coefficients.transpose();
  EXPECT_LT((X - Xp).cwiseAbs().maxCoeff(), 1e-9 * X.cwiseAbs().maxCoeff());
}

TEST(PartPca, RejectsBadInput) {
  auto model = testing::shape_test_model();
  EXPECT_THROW(spatial_triangle_parts(*model->tmpl, 0), InputError);
  EXPECT_THROW(part_wise_pca(model->shape.pca, std::vector<int>(10, 0)), InputError);
}

}  // namespace
}  // namespace bodymodel
