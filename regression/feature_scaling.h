// Feature and label scaling shared by the kernel regressors. Features are centred and divided by
// one global scale (the RMS distance of the training rows to their mean), so the geometry of the
// PCA space is kept (leading components stay dominant) while kernel widths become unit-free; or
// whitened (each feature by its own standard deviation).
#pragma once

#include <Eigen/Core>

namespace bodymodel {

struct FeatureScaling {
  Eigen::RowVectorXd mean;   // #features
  Eigen::RowVectorXd scale;  // #features, feature units per scaled unit (all equal unless whitened)
  double y_mean = 0, y_scale = 1;  // label unit

  // X #samples by #features, y #samples. whiten = false: one global scale for every feature (the
  // RMS distance of the rows to their mean); true: each feature divided by its own standard
  // deviation (every component weighs the same in the kernel).
  static FeatureScaling fit(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, bool whiten = false);
  Eigen::MatrixXd features(const Eigen::MatrixXd& X) const;  // (X − mean)/scale, row-wise
  Eigen::VectorXd feature(const Eigen::VectorXd& x) const;   // one row as a column
  Eigen::VectorXd label(const Eigen::VectorXd& y) const;     // (y − y_mean)/y_scale
};

// Squared Euclidean distances between the rows of A (#a by d) and B (#b by d): #a by #b.
Eigen::MatrixXd squared_distances(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B);

}  // namespace bodymodel
