#include "population/ansur_fit.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <set>

#include "core/error.h"

namespace bodymodel {

double ansur_tolerance(const std::string& name) {
  if (name == "weightkg") return 1.0;
  if (name.find("circumference") != std::string::npos) return 10.0;
  return 5.0;
}

const std::vector<std::string>& default_ansur_columns() {
  static const std::vector<std::string> c = {
      "stature", "weightkg", "chestcircumference", "waistcircumference", "buttockcircumference",
      "thighcircumference", "calfcircumference", "bicepscircumferenceflexed", "neckcircumferencebase",
      "shouldercircumference", "biacromialbreadth", "hipbreadth", "chestdepth", "acromialheight", "crotchheight",
      "iliocristaleheight", "kneeheightmidpatella", "sleeveoutseam"};
  return c;
}

namespace {

// The set's measurements that the table has, in the set's order.
std::vector<std::string> shared_names(const MeasurementSet& set, const AnsurTable& table) {
  std::vector<std::string> names;
  for (const auto& n : set.names)
    if (std::find(table.columns.begin(), table.columns.end(), n) != table.columns.end()) names.push_back(n);
  return names;
}

std::vector<int> prior_rows_of(const AnsurTable& table, const AnsurTable& prior_table, const AnsurFitOptions& o,
                               const std::vector<int>& fitted) {
  if (!o.prior_rows.empty()) return o.prior_rows;
  std::vector<int> rows;
  const bool same = &table == &prior_table || table.source == prior_table.source;
  const std::set<int> skip(fitted.begin(), fitted.end());
  for (int r = 0; r < static_cast<int>(prior_table.male.size()); ++r)
    if (!same || !skip.count(r)) rows.push_back(r);
  return rows;
}

void summarise(AnsurFitRun& run, const AnsurTable& table, const std::vector<std::string>& names,
               const std::vector<std::string>& given, const MeasurementPrior& prior) {
  for (const auto& name : names) {
    AnsurMeasurementSummary s;
    s.name = name;
    s.given = std::find(given.begin(), given.end(), name) != given.end();
    s.tolerance = ansur_tolerance(name);
    const int col = table.column(name);
    const int pi = static_cast<int>(std::find(prior.names.begin(), prior.names.end(), name) - prior.names.begin());
    double se_body = 0, se_reg = 0, sum = 0;
    int n = 0, within = 0;
    for (const auto& p : run.people) {
      const int k = static_cast<int>(std::find(p.fit.names.begin(), p.fit.names.end(), name) - p.fit.names.begin());
      const double truth = table.values(p.row, col), body = p.fit.measured(k);
      if (!std::isfinite(body)) continue;
      ++n;
      se_body += (body - truth) * (body - truth);
      sum += body - truth;
      within += std::abs(body - truth) <= s.tolerance;
      if (!s.given) {
        Eigen::VectorXd g(given.size());
        for (size_t i = 0; i < given.size(); ++i) g(i) = table.values(p.row, table.column(given[i]));
        Eigen::VectorXd e, sd;
        prior.condition(given, g, e, sd);
        se_reg += (e(pi) - truth) * (e(pi) - truth);
      }
    }
    if (n == 0) continue;
    s.rmse_body = std::sqrt(se_body / n);
    s.rmse_regression = s.given ? 0 : std::sqrt(se_reg / n);
    s.mean_error = sum / n;
    s.within = double(within) / n;
    run.summary.push_back(s);
  }
}

}  // namespace

AnsurFitRun fit_ansur_rows(const ProportionFitter& fitter, const MeasurementSet& set, const AnsurTable& table,
                           const AnsurTable& prior_table, const AnsurFitOptions& o, bool keep_bodies) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<std::string> names = shared_names(set, table);
  for (const auto& g : o.given) {
    if (set.index(g) < 0)
      throw InputError(fmt::format("--columns: '{}' is not a measurement the body can be fitted to (known: {})", g,
                                   fmt::join(set.names, ", ")));
    table.column(g);
  }
  std::vector<int> rows = o.rows;
  if (rows.empty())
    for (int r = 0; r < static_cast<int>(table.male.size()); ++r) rows.push_back(r);
  if (rows.empty()) throw InputError(fmt::format("'{}' has no rows to fit", table.source.string()));
  const int male = table.male.at(rows[0]);
  for (int r : rows)
    if (table.male.at(r) != male)
      throw InputError(fmt::format("'{}': fit one sex at a time (rows of both sexes were chosen)", table.source.string()));
  const std::vector<int> prior_rows = prior_rows_of(table, prior_table, o, rows);
  int same_sex = 0;
  for (int r : prior_rows) same_sex += prior_table.male.at(r) == male;
  if (same_sex < static_cast<int>(names.size()) + 2)
    throw InputError(fmt::format("'{}': {} soldiers of that sex are left to learn the population prior from (the "
                                 "ones being fitted are left out): fit a --sample of the file or give --prior FILE",
                                 prior_table.source.string(), same_sex));
  const MeasurementPrior prior = learn_measurement_prior(prior_table, male, names, prior_rows);
  const int age_col = table.column("Age");
  AnsurFitRun run;
  run.people.resize(rows.size());
  std::atomic<int> done{0};
  std::mutex progress_mutex;
  tbb::task_arena arena(o.jobs > 0 ? o.jobs : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(size_t(0), rows.size(), [&](size_t i) {
      const int r = rows[i];
      std::vector<ProportionTarget> targets;
      for (const auto& g : o.given) targets.push_back({g, table.values(r, table.column(g))});
      AnsurFitRow& row = run.people[i];
      row.id = table.ids.at(r);
      row.row = r;
      row.fit = fitter.fit(male ? Sex::male : Sex::female, std::clamp(table.values(r, age_col), 18.0, 90.0), targets,
                           prior);
      if (!keep_bodies) row.fit.V.resize(0, 3);
      const int d = ++done;
      if (o.progress) {
        std::lock_guard<std::mutex> lock(progress_mutex);
        o.progress(d, static_cast<int>(rows.size()));
      }
    });
  });
  run.template_self_intersections = fitter.template_self_intersections();
  for (const auto& p : run.people) {
    run.flipped_people += p.fit.flipped_triangles > 0;
    run.self_intersecting_people += p.fit.self_intersections > p.fit.reference_self_intersections;
    run.pushed_apart_people += p.fit.intersections_repaired > 0;
  }
  summarise(run, table, names, o.given, prior);
  run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return run;
}

}  // namespace bodymodel
