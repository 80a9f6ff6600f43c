#include "regression/regression_study.h"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <chrono>
#include <mutex>

#include "core/error.h"
#include "regression/linear_regressors.h"

namespace bodymodel {

const CrossValidationSummary& RegressionStudy::result(const std::string& regressor,
                                                      const std::string& label) const {
  for (const auto& r : results)
    if (r.regressor == regressor && r.label == label) return r;
  throw InputError("no result for regressor '" + regressor + "' and label '" + label + "'");
}

RegressionStudy run_regression_study(const Eigen::MatrixXd& X, const Eigen::MatrixXd& Y,
                                     const std::vector<std::string>& labels,
                                     const std::vector<int>& groups,
                                     const RegressionStudyOptions& options,
                                     const ProgressCallback& progress) {
  const auto start = std::chrono::steady_clock::now();
  if (Y.rows() != X.rows())
    throw InputError("regression study: " + std::to_string(X.rows()) + " feature rows but " +
                     std::to_string(Y.rows()) + " label rows");
  if (static_cast<Eigen::Index>(labels.size()) != Y.cols())
    throw InputError("regression study: " + std::to_string(labels.size()) + " label names for " +
                     std::to_string(Y.cols()) + " label columns");
  if (!groups.empty() && static_cast<Eigen::Index>(groups.size()) != X.rows())
    throw InputError("regression study: " + std::to_string(groups.size()) + " subject indices for " +
                     std::to_string(X.rows()) + " rows");
  if (!X.allFinite()) throw InputError("regression study: the features contain NaN or infinite values");
  const int L = static_cast<int>(labels.size());
  const int R = static_cast<int>(options.regressors.size());
  const int F = options.cross_validation.folds;
  std::vector<std::unique_ptr<Regressor>> prototypes;
  for (const auto& name : options.regressors) prototypes.push_back(make_regressor(name));

  // Per label: usable rows, their data and the folds (identical for every regressor).
  struct LabelData {
    std::vector<int> rows, fold_of, groups;
    Eigen::MatrixXd X;
    Eigen::VectorXd y;
    std::vector<std::pair<std::vector<int>, std::vector<int>>> splits;
  };
  std::vector<LabelData> data(L);
  for (int l = 0; l < L; ++l) {
    LabelData& d = data[l];
    d.rows = usable_label_rows(Y.col(l), labels[l], 2);
    d.X = select_rows(X, d.rows);
    d.y = select_rows(Eigen::VectorXd(Y.col(l)), d.rows);
    d.groups = select_rows(groups, d.rows);
    try {
      d.fold_of = grouped_folds(d.groups, static_cast<int>(d.rows.size()), F, options.cross_validation.seed);
    } catch (const InputError& e) {
      throw InputError("label '" + labels[l] + "': " + e.what());
    }
    d.splits = fold_splits(d.fold_of, F);
  }

  // Task list: (label, regressor, fold) cross-validation fits, then (label, regressor) full fits
  // for directions, then (label) filtered curves.
  struct Task { int kind, l, r, f; };
  std::vector<Task> tasks;
  for (int r = 0; r < R; ++r)
    for (int l = 0; l < L; ++l)
      for (int f = 0; f < F; ++f) tasks.push_back({0, l, r, f});
  if (options.directions)
    for (int r = 0; r < R; ++r)
      for (int l = 0; l < L; ++l) tasks.push_back({1, l, r, 0});
  if (options.filtered_curve)
    for (int l = 0; l < L; ++l) tasks.push_back({2, l, 0, 0});

  RegressionStudy study;
  study.labels = labels;
  std::vector<std::vector<Eigen::VectorXd>> fold_predictions(R * L, std::vector<Eigen::VectorXd>(F));
  std::vector<std::vector<std::string>> fold_descriptions(R * L, std::vector<std::string>(F));
  std::vector<MorphDirectionSpread> spreads(R * L);
  study.filtered_curves.resize(L);

  std::atomic<int> done{0};
  std::mutex progress_mutex;
  std::atomic<bool> cancelled{false};
  auto run_task = [&](const Task& t) {
    if (cancelled) return;
    const LabelData& d = data[t.l];
    const int k = t.r * L + t.l;
    if (t.kind == 0) {
      const auto& [train, test] = d.splits[t.f];
      auto reg = prototypes[t.r]->clone();
      reg->fit(select_rows(d.X, train), select_rows(d.y, train), select_rows(d.groups, train));
      fold_predictions[k][t.f] = reg->predict_rows(select_rows(d.X, test));
      fold_descriptions[k][t.f] = reg->describe();
    } else if (t.kind == 1) {
      auto reg = prototypes[t.r]->clone();
      reg->fit(d.X, d.y, d.groups);
      spreads[k] = morph_direction_spread(morph_directions(*reg, d.X));
    } else {
      study.filtered_curves[t.l] =
          filtered_linear_curve(d.X, d.y, d.fold_of, F, options.curve_max_components);
    }
    const int n = ++done;
    if (progress) {
      std::lock_guard<std::mutex> lock(progress_mutex);
      try {
        report_progress(progress, static_cast<double>(n) / tasks.size(), "cross-validating regressors");
      } catch (const Cancelled&) {
        cancelled = true;
      }
    }
  };
  const int threads = options.jobs > 0 ? options.jobs : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  arena.execute([&] {
    tbb::parallel_for(size_t{0}, tasks.size(), [&](size_t i) { run_task(tasks[i]); });
  });
  if (cancelled) throw Cancelled{};

  for (int r = 0; r < R; ++r)
    for (int l = 0; l < L; ++l) {
      const LabelData& d = data[l];
      const int k = r * L + l;
      CrossValidationSummary s;
      s.regressor = options.regressors[r];
      s.label = labels[l];
      s.folds = F;
      s.samples = static_cast<int>(d.rows.size());
      s.skipped_missing = static_cast<int>(Y.rows()) - s.samples;
      s.rows = d.rows;
      s.predictions.resize(d.rows.size());
      for (int f = 0; f < F; ++f) {
        const auto& test = d.splits[f].second;
        for (size_t i = 0; i < test.size(); ++i) s.predictions(test[i]) = fold_predictions[k][f](i);
      }
      if (!s.predictions.allFinite())
        throw NumericalError("regression study: " + s.regressor + " produced a non-finite prediction for '" +
                             s.label + "'");
      s.fold_descriptions = fold_descriptions[k];
      s.rmse = root_mean_square_error(s.predictions, d.y);
      s.mae = (s.predictions - d.y).cwiseAbs().mean();
      study.results.push_back(std::move(s));
      if (options.directions) study.directions.push_back({options.regressors[r], labels[l], spreads[k]});
    }
  study.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return study;
}

}  // namespace bodymodel
