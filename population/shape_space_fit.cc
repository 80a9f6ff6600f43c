#include "population/shape_space_fit.h"

#include <algorithm>
#include <chrono>
#include <numeric>
#include <random>

#include "core/error.h"
#include "population/ansur_fit.h"

namespace bodymodel {

Eigen::VectorXd shape_space_row(const MakeHuman& mh, const ProportionFit& f) {
  const Eigen::Index nm = static_cast<Eigen::Index>(mh.measure_modifier_names().size());
  const Eigen::Index ns = static_cast<Eigen::Index>(mh.shape_modifiers().size());
  Eigen::VectorXd row = Eigen::VectorXd::Zero(8 + nm + ns);
  const MacroSettings& m = f.sliders;
  row.head(8) << m.gender, m.age, m.muscle, m.weight, m.height, m.proportions, m.cup, m.firmness;
  if (f.measure_modifiers.size() == nm) row.segment(8, nm) = f.measure_modifiers;
  if (f.shape_modifiers.size() == ns) row.tail(ns) = f.shape_modifiers;
  return row;
}

ShapeSpaceFitRun ansur_shape_space(const MakeHuman& mh, const std::vector<AnsurTable>& tables,
                                   const ShapeSpaceFitOptions& o) {
  if (tables.empty()) throw InputError("shape space: no ANSUR table given");
  if (o.components < 1) throw InputError("shape space: components must be at least 1");
  const auto t0 = std::chrono::steady_clock::now();
  const MeasurementSet set = ansur_measurement_set(mh);
  const ProportionFitter fitter(mh, set);
  std::vector<std::vector<int>> rows(tables.size());
  int total = 0;
  for (size_t t = 0; t < tables.size(); ++t) {
    std::vector<int> all(tables[t].ids.size());
    std::iota(all.begin(), all.end(), 0);
    std::mt19937_64 rng(o.seed + t);
    std::shuffle(all.begin(), all.end(), rng);
    if (o.per_table > 0 && int(all.size()) > o.per_table) all.resize(o.per_table);
    std::sort(all.begin(), all.end());
    rows[t] = all;
    total += int(all.size());
  }
  const std::vector<std::string> names = shape_space_parameter_names(mh);
  Eigen::MatrixXd X(total, names.size());
  ShapeSpaceFitRun run;
  std::string source;
  std::vector<int> male;
  int done = 0;
  for (size_t t = 0; t < tables.size(); ++t) {
    AnsurFitOptions fo;
    fo.given = default_ansur_columns();
    fo.rows = rows[t];
    fo.jobs = o.jobs;
    const int before = done;
    if (o.progress) fo.progress = [&](int d, int) { o.progress(before + d, total); };
    const AnsurFitRun r = fit_ansur_rows(fitter, set, tables[t], tables[t], fo, false);
    for (const AnsurFitRow& p : r.people) {
      male.push_back(tables[t].male[p.row]);
      X.row(done++) = shape_space_row(mh, p.fit).transpose();
    }
    run.flipped_people += r.flipped_people;
    source += (source.empty() ? "" : ", ") + std::to_string(r.people.size()) + " of " +
              tables[t].source.filename().string();
  }
  run.space = learn_shape_space(names, X.topRows(done), o.components,
                                "ANSUR II soldiers fitted to " + std::to_string(default_ansur_columns().size()) +
                                    " measurements: " + source,
                                male);
  run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return run;
}

}  // namespace bodymodel
