#include "regression/svr.h"

#include <libsvm/svm.h>

#include <cmath>
#include <sstream>
#include <limits>
#include <mutex>

#include "core/error.h"
#include "regression/cross_validation.h"

namespace bodymodel {

namespace {

void silent(const char*) {}

void silence_libsvm() {
  static std::once_flag once;
  std::call_once(once, [] { svm_set_print_string_function(&silent); });
}

}  // namespace

struct SvrRegressor::LibsvmModel {
  std::vector<std::vector<svm_node>> nodes;  // one terminated row per training sample
  std::vector<svm_node*> rows;
  std::vector<double> targets;
  svm_problem problem{};
  svm_parameter param{};
  svm_model* model = nullptr;

  LibsvmModel(const Eigen::MatrixXd& Z, const Eigen::VectorXd& t, double C, double epsilon,
              double gamma, double tolerance) {
    silence_libsvm();
    const int n = static_cast<int>(Z.rows()), d = static_cast<int>(Z.cols());
    nodes.resize(n);
    rows.resize(n);
    targets.assign(t.data(), t.data() + n);
    for (int i = 0; i < n; ++i) {
      nodes[i].resize(d + 1);
      for (int j = 0; j < d; ++j) nodes[i][j] = svm_node{j + 1, Z(i, j)};
      nodes[i][d] = svm_node{-1, 0};
      rows[i] = nodes[i].data();
    }
    problem.l = n;
    problem.y = targets.data();
    problem.x = rows.data();
    param.svm_type = EPSILON_SVR;
    param.kernel_type = RBF;
    param.gamma = gamma;
    param.C = C;
    param.p = epsilon;
    param.eps = tolerance;
    param.cache_size = 20;
    param.shrinking = 1;
    param.probability = 0;
    if (const char* err = svm_check_parameter(&problem, &param))
      throw InputError(std::string("svr: libsvm rejected the parameters: ") + err);
    model = svm_train(&problem, &param);
    if (!model) throw NumericalError("svr: libsvm training failed");
  }
  ~LibsvmModel() {
    if (model) svm_free_and_destroy_model(&model);
  }
  LibsvmModel(const LibsvmModel&) = delete;
  LibsvmModel& operator=(const LibsvmModel&) = delete;

  // Support-vector expansion: rows of Z (scaled) that are SVs, their coefficients, and ρ.
  void expansion(const Eigen::MatrixXd& Z, Eigen::MatrixXd& sv, Eigen::VectorXd& coef, double& rho) const {
    const int nsv = svm_get_nr_sv(model);
    std::vector<int> idx(nsv);
    svm_get_sv_indices(model, idx.data());
    sv.resize(nsv, Z.cols());
    coef.resize(nsv);
    for (int k = 0; k < nsv; ++k) {
      sv.row(k) = Z.row(idx[k] - 1);
      coef(k) = model->sv_coef[0][k];
    }
    rho = model->rho[0];
  }
};

namespace {

// Standardised-space decision values of an expansion at the rows of Zq.
Eigen::VectorXd decision(const Eigen::MatrixXd& Zq, const Eigen::MatrixXd& sv, const Eigen::VectorXd& coef,
                         double rho, double gamma) {
  if (sv.rows() == 0) return Eigen::VectorXd::Constant(Zq.rows(), -rho);
  const Eigen::MatrixXd K = (-gamma * squared_distances(Zq, sv)).array().exp().matrix();
  return (K * coef).array() - rho;
}

}  // namespace

void SvrRegressor::fit(const Eigen::MatrixXd& X, const Eigen::VectorXd& y, const std::vector<int>& groups) {
  check_regression_input(X, y, groups, 3, "svr");
  if (options_.C.empty() || options_.epsilon.empty() || options_.gamma.empty())
    throw InputError("svr: the C, epsilon and gamma grids must not be empty");
  scaling_ = FeatureScaling::fit(X, y, options_.whiten);
  const Eigen::MatrixXd Z = scaling_.features(X);
  const Eigen::VectorXd t = scaling_.label(y);

  const bool search = options_.C.size() * options_.epsilon.size() * options_.gamma.size() > 1;
  C_ = options_.C[0], epsilon_ = options_.epsilon[0], gamma_ = options_.gamma[0];
  if (search) {
    int subjects = static_cast<int>(X.rows());
    if (!groups.empty()) {
      std::vector<int> g = groups;
      std::sort(g.begin(), g.end());
      subjects = static_cast<int>(std::unique(g.begin(), g.end()) - g.begin());
    }
    const int inner = std::min(options_.inner_folds, subjects);
    const auto splits =
        fold_splits(grouped_folds(groups, static_cast<int>(X.rows()), inner, options_.inner_seed), inner);
    double best = std::numeric_limits<double>::infinity();
    for (double gamma : options_.gamma)
      for (double C : options_.C)
        for (double eps : options_.epsilon) {
          double sse = 0;
          for (const auto& [train, test] : splits) {
            // Scaling is that of the whole training set: it is label-free for features and a
            // monotone affine map for the label, so it leaks nothing the fold could exploit.
            const Eigen::MatrixXd Ztr = select_rows(Z, train);
            LibsvmModel m(Ztr, select_rows(t, train), C, eps, gamma, options_.tolerance);
            Eigen::MatrixXd sv;
            Eigen::VectorXd coef;
            double rho;
            m.expansion(Ztr, sv, coef, rho);
            sse += (decision(select_rows(Z, test), sv, coef, rho, gamma) - select_rows(t, test)).squaredNorm();
          }
          if (sse < best) best = sse, C_ = C, epsilon_ = eps, gamma_ = gamma;
        }
  }
  model_ = std::make_shared<LibsvmModel>(Z, t, C_, epsilon_, gamma_, options_.tolerance);
  model_->expansion(Z, sv_, coef_, rho_);
}

double SvrRegressor::predict(const Eigen::VectorXd& x) const {
  if (!model_) throw InputError("svr: predict called before fit");
  if (x.size() != scaling_.mean.size())
    throw InputError("svr: expected " + std::to_string(scaling_.mean.size()) + " features, found " +
                     std::to_string(x.size()));
  const Eigen::MatrixXd z = scaling_.feature(x).transpose();
  return scaling_.y_mean + scaling_.y_scale * decision(z, sv_, coef_, rho_, gamma_)(0);
}

Eigen::VectorXd SvrRegressor::gradient(const Eigen::VectorXd& x) const {
  if (!model_) throw InputError("svr: gradient called before fit");
  if (x.size() != scaling_.mean.size())
    throw InputError("svr: expected " + std::to_string(scaling_.mean.size()) + " features, found " +
                     std::to_string(x.size()));
  const Eigen::VectorXd z = scaling_.feature(x);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(z.size());
  for (Eigen::Index k = 0; k < sv_.rows(); ++k) {
    const Eigen::VectorXd diff = z - sv_.row(k).transpose();
    g += coef_(k) * std::exp(-gamma_ * diff.squaredNorm()) * (-2.0 * gamma_) * diff;
  }
  return scaling_.y_scale * g.cwiseQuotient(scaling_.scale.transpose());
}

double SvrRegressor::predict_with_libsvm(const Eigen::VectorXd& x) const {
  if (!model_) throw InputError("svr: predict called before fit");
  const Eigen::VectorXd z = scaling_.feature(x);
  std::vector<svm_node> nodes(z.size() + 1);
  for (Eigen::Index j = 0; j < z.size(); ++j) nodes[j] = svm_node{static_cast<int>(j + 1), z(j)};
  nodes[z.size()] = svm_node{-1, 0};
  return scaling_.y_mean + scaling_.y_scale * svm_predict(model_->model, nodes.data());
}

std::unique_ptr<Regressor> SvrRegressor::clone() const { return std::make_unique<SvrRegressor>(options_); }

std::string SvrRegressor::describe() const {
  std::ostringstream s;
  s << "C=" << C_ << " epsilon=" << epsilon_ << " gamma=" << gamma_ << " (" << coef_.size()
    << " support vectors)";
  return s.str();
}

}  // namespace bodymodel
