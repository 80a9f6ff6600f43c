// Regression (regression/) on plain matrices: the regressors and cross-validation.
#include <fmt/format.h>

#include "core/error.h"
#include "python/common.h"
#include "regression/cross_validation.h"
#include "regression/regressor.h"

namespace bodymodel::py {

namespace {

using namespace pybind11::literals;

class PyRegressor {
 public:
  explicit PyRegressor(const std::string& name) : r_(make_regressor(name)) {}
  void fit(const pyb::handle& X, const pyb::handle& y, const std::vector<int>& groups) {
    Eigen::MatrixXd Xm = matrix(X, "X");
    Eigen::VectorXd yv = vector(y, "y");
    pyb::gil_scoped_release nogil;
    r_->fit(Xm, yv, groups);
    fitted_ = true;
  }
  pyb::array_t<double> predict(const pyb::handle& X) const {
    check_fitted();
    Eigen::MatrixXd Xm = matrix(X, "X");
    pyb::gil_scoped_release nogil;
    Eigen::VectorXd p = r_->predict_rows(Xm);
    pyb::gil_scoped_acquire gil;
    return to_array(p);
  }
  pyb::array_t<double> gradient(const pyb::handle& x) const {
    check_fitted();
    return to_array(r_->gradient(vector(x, "x")));
  }
  const Regressor& get() const { return *r_; }

 private:
  void check_fitted() const {
    if (!fitted_) throw InputError(r_->name() + ": call fit(X, y) before predicting");
  }
  std::unique_ptr<Regressor> r_;
  bool fitted_ = false;
};

}  // namespace

void bind_regression(pyb::module_& m) {
  // ---- regression --------------------------------------------------------------------------------
  m.def("regressor_names", &regressor_names, "The regressors make_regressor knows, in report order.");
  pyb::class_<PyRegressor>(m, "Regressor", R"(A regressor of one label on features (regression/regressor.h).

Regressor(name): simple_linear, filtered_linear, svr, gaussian_process (see regressor_names()).)")
      .def(pyb::init<const std::string&>(), "name"_a)
      .def("fit", &PyRegressor::fit, "X"_a, "y"_a, "groups"_a = std::vector<int>{},
           "fit(X, y, groups=[]): X (N, k) features, y (N,) label, groups (N,) subject of each row or empty. Releases the GIL.")
      .def("predict", &PyRegressor::predict, "X"_a, "predict(X) -> (N,) predictions for rows X (N, k), label unit.")
      .def("gradient", &PyRegressor::gradient, "x"_a, "gradient(x) -> (k,): d(prediction)/dx at x (the morph direction).")
      .def_property_readonly("name", [](const PyRegressor& r) { return r.get().name(); })
      .def("describe", [](const PyRegressor& r) { return r.get().describe(); },
           "The hyper-parameters the last fit chose, human-readable.");
  m.def("cross_validate", [](const std::string& name, const pyb::handle& X, const pyb::handle& y,
                             const std::vector<int>& groups, int folds, unsigned seed, const std::string& label) {
          auto proto = make_regressor(name);
          Eigen::MatrixXd Xm = matrix(X, "X");
          Eigen::VectorXd yv = vector(y, "y", /*allow_nan=*/true);
          CrossValidationOptions o;
          o.folds = folds, o.seed = seed;
          CrossValidationSummary s;
          {
            pyb::gil_scoped_release nogil;
            s = cross_validate(*proto, Xm, yv, groups, o, label);
          }
          return pyb::dict("regressor"_a = s.regressor, "label"_a = s.label, "rmse"_a = s.rmse, "mae"_a = s.mae,
                           "folds"_a = s.folds, "samples"_a = s.samples, "skipped_missing"_a = s.skipped_missing,
                           "rows"_a = s.rows, "predictions"_a = to_array(s.predictions),
                           "fold_descriptions"_a = s.fold_descriptions);
        }, "name"_a, "X"_a, "y"_a, "groups"_a = std::vector<int>{}, "folds"_a = 10, "seed"_a = 1u, "label"_a = "label",
        R"(cross_validate(name, X, y, groups=[], folds=10, seed=1, label='label') -> dict

Subject-grouped k-fold cross-validation of regressor `name` on X (N, k), y (N,) (NaN rows are
skipped): rmse and mae (label unit), the held-out prediction of each evaluated row (rows,
predictions) and each fold's chosen hyper-parameters. Seeded: the same call gives the same folds.)");
}

}  // namespace bodymodel::py
