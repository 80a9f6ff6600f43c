// The cleaning's figures against a simulated capture's truth (markers/clean.h).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>

#include "core/error.h"
#include "core/statistics.h"
#include "markers/clean.h"

namespace bodymodel {

Eigen::VectorXd spline_fill(const Eigen::VectorXd& x) {
  std::vector<int> k;
  for (int t = 0; t < x.size(); ++t)
    if (!std::isnan(x(t))) k.push_back(t);
  Eigen::VectorXd out = Eigen::VectorXd::Constant(x.size(), std::numeric_limits<double>::quiet_NaN());
  const int n = static_cast<int>(k.size());
  if (n == 0) return out;
  if (n == 1) {
    out(k[0]) = x(k[0]);
    return out;
  }
  // Second derivatives M of the natural spline (M_0 = M_{n-1} = 0): a tridiagonal system.
  std::vector<double> M(n, 0.0), c(n, 0.0), d(n, 0.0);
  for (int j = 1; j + 1 < n; ++j) {
    const double h0 = k[j] - k[j - 1], h1 = k[j + 1] - k[j];
    const double a = h0 / 6, b = (h0 + h1) / 3, cc = h1 / 6;
    const double rhs = (x(k[j + 1]) - x(k[j])) / h1 - (x(k[j]) - x(k[j - 1])) / h0;
    const double denom = b - a * c[j - 1];
    c[j] = cc / denom;
    d[j] = (rhs - a * d[j - 1]) / denom;
  }
  for (int j = n - 2; j >= 1; --j) M[j] = d[j] - c[j] * M[j + 1];
  for (int j = 0; j + 1 < n; ++j) {
    const double h = k[j + 1] - k[j];
    for (int t = k[j]; t <= k[j + 1]; ++t) {
      const double A = (k[j + 1] - t) / h, B = (t - k[j]) / h;
      out(t) = A * x(k[j]) + B * x(k[j + 1]) + ((A * A * A - A) * M[j] + (B * B * B - B) * M[j + 1]) * h * h / 6;
    }
  }
  return out;
}

namespace {

// Mean distance from a capture column's samples to a truth column over the samples' frames.
double mean_distance(const MarkerData& c, int column, const MarkerData& truth, int marker) {
  double sum = 0;
  int n = 0;
  for (int t = 0; t < c.frame_count(); ++t)
    if (c.present(t, column)) sum += (c.at(t, column) - truth.at(t, marker)).norm(), ++n;
  return n ? sum / n : std::nan("");
}

void count_merges(const MarkerData& capture, const CleanResult& res, const MarkerData& truth,
                  const std::map<std::string, int>& col, const std::map<std::string, int>& tcol, CleanEvaluation& e) {
  for (const auto& m : res.report.merges)
    if (!(mean_distance(capture, col.at(m.piece), truth, tcol.at(m.marker)) <= 10.0)) ++e.wrong_merges;
  for (const auto& p : res.report.unmerged) {
    const int c = col.at(p);
    int first = 0;
    while (!capture.present(first, c)) ++first;
    int nearest = 0;
    double best = 1e300;
    for (int m = 0; m < truth.marker_count(); ++m) {
      const double d = (capture.at(first, c) - truth.at(first, m)).norm();
      if (d < best) best = d, nearest = m;
    }
    if (mean_distance(capture, c, truth, nearest) <= 10.0) ++e.missed_pieces;
  }
}

}  // namespace

CleanEvaluation evaluate_cleaning(const MarkerData& capture, const CleanResult& res, const MarkerData& truth) {
  std::map<std::string, int> col, tcol;
  for (int m = 0; m < capture.marker_count(); ++m) col[capture.labels[m]] = m;
  for (int m = 0; m < truth.marker_count(); ++m) tcol[truth.labels[m]] = m;
  if (truth.frame_count() != capture.frame_count())
    throw InputError("markers evaluation: the truth has " + std::to_string(truth.frame_count()) + " frames, the capture " +
                     std::to_string(capture.frame_count()));
  for (const auto& l : res.cleaned.labels)
    if (!tcol.count(l)) throw InputError("markers evaluation: marker '" + l + "' is not in the truth");
  CleanEvaluation e;
  count_merges(capture, res, truth, col, tcol, e);
  std::vector<double> all, interior, spline, mid, mid_spline;
  for (int i = 0; i < res.cleaned.marker_count(); ++i) {
    const int m = tcol.at(res.cleaned.labels[i]);
    Eigen::MatrixX3d s(res.merged.frame_count(), 3);
    for (int k = 0; k < 3; ++k) s.col(k) = spline_fill(res.merged.xyz.col(3 * i + k));
    const int T = res.merged.frame_count();
    for (int t = 0, end = 0; t < T; t = std::max(t + 1, end)) {
      if (res.merged.present(t, i)) continue;
      end = t;
      while (end < T && !res.merged.present(end, i)) ++end;  // the hole is [t, end)
      for (int k = t; k < end; ++k) {
        const double err = (res.cleaned.at(k, i) - truth.at(k, m)).norm();
        all.push_back(err);
        if (!s.row(k).allFinite()) continue;
        const double spl = (s.row(k).transpose() - truth.at(k, m)).norm();
        interior.push_back(err), spline.push_back(spl);
        if (end - t >= 5 && end - t <= 60) mid.push_back(err), mid_spline.push_back(spl);
      }
    }
  }
  e.gap_5_60 = static_cast<long>(mid.size());
  e.median_5_60_mm = median(mid);
  e.median_spline_5_60_mm = median(mid_spline);
  e.ratio_5_60 = e.median_5_60_mm / e.median_spline_5_60_mm;
  e.filled = static_cast<long>(all.size());
  e.interior_filled = static_cast<long>(interior.size());
  e.median_fill_mm = median(all);
  e.p95_fill_mm = percentile(all, 95.0);
  double sum = 0;
  for (double v : all) sum += v;
  e.mean_fill_mm = all.empty() ? std::nan("") : sum / all.size();
  e.median_interior_mm = median(interior);
  e.median_spline_mm = median(spline);
  e.ratio_to_spline = e.median_interior_mm / e.median_spline_mm;
  return e;
}

nlohmann::json evaluation_json(const CleanEvaluation& e) {
  return {{"wrong_merges", e.wrong_merges}, {"missed_pieces", e.missed_pieces}, {"filled_samples", e.filled},
          {"median_fill_mm", e.median_fill_mm}, {"mean_fill_mm", e.mean_fill_mm}, {"p95_fill_mm", e.p95_fill_mm},
          {"interior_filled_samples", e.interior_filled}, {"median_interior_fill_mm", e.median_interior_mm},
          {"median_spline_mm", e.median_spline_mm}, {"ratio_to_spline", e.ratio_to_spline},
          {"samples_in_holes_of_5_to_60_frames", e.gap_5_60}, {"median_fill_5_to_60_mm", e.median_5_60_mm},
          {"median_spline_5_to_60_mm", e.median_spline_5_60_mm}, {"ratio_to_spline_5_to_60", e.ratio_5_60}};
}

}  // namespace bodymodel
