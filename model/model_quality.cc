#include "model/model_quality.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <numeric>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/statistics.h"
#include "encoding/relative_rotation_decoder.h"
#include "model/format.h"

namespace bodymodel {

namespace {

Eigen::VectorXd flatten(const Eigen::MatrixX3d& V) {
  Eigen::VectorXd v(3 * V.rows());
  for (Eigen::Index i = 0; i < V.rows(); ++i) v.segment<3>(3 * i) = V.row(i).transpose();
  return v;
}

Eigen::MatrixX3d unflatten(const Eigen::VectorXd& v) {
  Eigen::MatrixX3d V(v.size() / 3, 3);
  for (Eigen::Index i = 0; i < V.rows(); ++i) V.row(i) = v.segment<3>(3 * i).transpose();
  return V;
}

// Mean vertex error after the best rigid fit of A onto B.
double rigid_mean_error(const Eigen::MatrixX3d& A, const Eigen::MatrixX3d& B) {
  return (apply(fit_rigid_motion(A, B), A) - B).rowwise().norm().mean();
}

double nearest_training_distance(const Eigen::MatrixX3d& sample, const std::vector<Eigen::MatrixX3d>& train) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& T : train) best = std::min(best, rigid_mean_error(sample, T));
  return best;
}

}  // namespace


Eigen::MatrixX3d VertexPcaModel::mesh(const Eigen::VectorXd& c) const {
  return unflatten(pca.mean + pca.basis.leftCols(c.size()) * c);
}

VertexPcaModel build_vertex_pca(const std::vector<Eigen::MatrixX3d>& meshes) {
  if (meshes.size() < 2) throw InputError(fmt::format("vertex PCA needs at least 2 meshes, got {}", meshes.size()));
  const Eigen::Index nv = meshes[0].rows();
  for (size_t i = 1; i < meshes.size(); ++i)
    if (meshes[i].rows() != nv)
      throw InputError(fmt::format("vertex PCA: mesh {} has {} vertices, mesh 0 has {}", i, meshes[i].rows(), nv));
  VertexPcaModel m;
  // Reference: mean after aligning to the first, then everything re-aligned to that mean.
  Eigen::MatrixX3d ref = Eigen::MatrixX3d::Zero(nv, 3);
  for (const auto& V : meshes) ref += apply(fit_rigid_motion(V, meshes[0]), V);
  ref /= static_cast<double>(meshes.size());
  m.reference = ref;
  Eigen::MatrixXd X(3 * nv, meshes.size());
  for (size_t i = 0; i < meshes.size(); ++i) X.col(i) = flatten(apply(fit_rigid_motion(meshes[i], ref), meshes[i]));
  m.pca = fit_pca(X, {1.0, -1});
  return m;
}

VertexPcaFit fit_vertex_pca(const VertexPcaModel& model, const Eigen::MatrixX3d& Y, int K, int max_iterations,
                            double tolerance_mm) {
  if (K < 1 || K > model.pca.component_count())
    throw InputError(fmt::format("vertex PCA fit: {} components requested, the model has {}", K,
                                 model.pca.component_count()));
  if (Y.rows() * 3 != model.pca.dimension())
    throw InputError(fmt::format("vertex PCA fit: the mesh has {} vertices, the model {}", Y.rows(),
                                 model.pca.dimension() / 3));
  const auto B = model.pca.basis.leftCols(K);
  VertexPcaFit out;
  RigidMotion to_model = fit_rigid_motion(Y, model.reference);  // target → model frame
  Eigen::MatrixX3d placed;
  for (int it = 0; it < max_iterations; ++it) {
    ++out.iterations;
    const Eigen::VectorXd y = flatten(apply(to_model, Y));
    out.coefficients = B.transpose() * (y - model.pca.mean);
    const Eigen::MatrixX3d M = model.mesh(out.coefficients);
    const RigidMotion back = fit_rigid_motion(M, Y);
    Eigen::MatrixX3d next = apply(back, M);
    const double moved = placed.size() ? (next - placed).rowwise().norm().maxCoeff() : 1e300;
    placed = std::move(next);
    // The inverse of `back` maps the target into the model frame for the next projection.
    to_model.R = back.R.transpose();
    to_model.t = -back.R.transpose() * back.t;
    if (moved < tolerance_mm) break;
  }
  out.V = placed;
  out.vertex_error = (placed - Y).rowwise().norm();
  return out;
}

std::vector<int> default_component_grid(int max) {
  std::vector<int> k;
  for (int v : {1, 2, 5, 10, 20, 40, 80, 160, 320})
    if (v < max) k.push_back(v);
  k.push_back(max);
  return k;
}

ModelQuality evaluate_model_quality(const BodyModel& model, const std::vector<Eigen::MatrixX3d>& train,
                                    const std::vector<Eigen::MatrixX3d>& test, const std::vector<std::string>& names,
                                    double total_variance, const ModelQualityOptions& o,
                                    const ProgressCallback& progress) {
  o.fit.validate();
  if (test.empty()) throw InputError("model quality: no test meshes");
  if (names.size() != test.size()) throw InputError("model quality: one name per test mesh needed");
  if (o.specificity_samples < 0) throw InputError("model quality: specificity samples must be ≥ 0");
  const int nv = model.tmpl->vertex_count();
  for (size_t i = 0; i < test.size(); ++i)
    if (test[i].rows() != nv)
      throw InputError(fmt::format("test mesh '{}' has {} vertices, the model's template has {}", names[i],
                                   test[i].rows(), nv));
  for (size_t i = 0; i < train.size(); ++i)
    if (train[i].rows() != nv)
      throw InputError(fmt::format("training mesh {} has {} vertices, the model's template has {}", i, train[i].rows(), nv));
  for (int K : o.components)
    if (K < 1) throw InputError(fmt::format("model quality: component counts must be ≥ 1, got {}", K));
  const Pca& pca = model.full.pca;
  VertexPcaModel vpca;
  const bool baseline = o.vertex_baseline && train.size() >= 2;
  if (baseline) vpca = build_vertex_pca(train);

  struct Job {
    std::string model;
    int K;
  };
  auto grid = [&](int max) {
    std::vector<int> ks = o.components.empty() ? default_component_grid(max) : o.components;
    for (auto& k : ks) k = std::min(k, max);
    std::sort(ks.begin(), ks.end());
    ks.erase(std::unique(ks.begin(), ks.end()), ks.end());
    return ks;
  };
  std::vector<Job> jobs;
  for (int K : grid(pca.component_count())) jobs.push_back({"rre", K});
  if (baseline)
    for (int K : grid(vpca.pca.component_count())) jobs.push_back({"vertex_pca", K});

  ModelFitter fitter(model.tmpl, model.mean, pca);
  RelativeRotationDecoder decoder(model.tmpl);
  ModelQuality out;
  out.rows.resize(jobs.size());
  out.pooled_errors.resize(jobs.size());
  out.specificity_samples_mm.resize(jobs.size());
  const double total_units = static_cast<double>(jobs.size()) * static_cast<double>(test.size()) +
                             (train.empty() ? 0.0 : 6.0 * o.specificity_samples / 20.0);
  double done = 0;
  std::mutex mtx;
  auto tick = [&](double units, const std::string& what) {
    std::lock_guard<std::mutex> lock(mtx);
    done += units;
    report_progress(progress, std::min(1.0, done / total_units), what);
  };
  const double rre_total = total_variance > 0 ? total_variance : pca.eigenvalues.sum();
  const double vpca_total = baseline ? vpca.pca.eigenvalues.sum() : 1.0;  // all components kept
  // Generalisation: every test mesh at every K. The rotation-invariant fits run K ascending,
  // each started from the previous K's coefficients (a continuation: the (K−1)-component optimum
  // is a point of the K-component space), the first from the projection.
  std::vector<std::vector<Eigen::VectorXd>> errors(jobs.size(), std::vector<Eigen::VectorXd>(test.size()));
  std::vector<std::vector<double>> seconds(jobs.size(), std::vector<double>(test.size(), 0.0));
  std::vector<std::vector<int>> converged(jobs.size(), std::vector<int>(test.size(), -1));
  std::vector<std::vector<std::pair<double, int>>> starts(
      jobs.size(), std::vector<std::pair<double, int>>(test.size(), {std::numeric_limits<double>::quiet_NaN(), 0}));
  tbb::parallel_for(0, static_cast<int>(test.size()), [&](int t) {
    Eigen::VectorXd previous;
    for (size_t j = 0; j < jobs.size(); ++j) {
      const auto t0 = std::chrono::steady_clock::now();
      if (jobs[j].model == "rre") {
        ModelFitOptions fo = o.fit;
        fo.components = jobs[j].K;
        if (previous.size() > 0) {
          fo.start = previous;
          fo.continuation_components = 0;
        }
        ModelFit f = fitter.fit(test[t], fo);
        previous = f.coefficients;
        errors[j][t] = f.vertex_error;
        converged[j][t] = f.summary.converged ? 1 : 0;
        starts[j][t] = {f.summary.start_mean_mm, f.summary.iterations};
      } else {
        errors[j][t] = fit_vertex_pca(vpca, test[t], jobs[j].K).vertex_error;
      }
      seconds[j][t] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      tick(1, fmt::format("{} K={} {}", jobs[j].model, jobs[j].K, names[t]));
    }
  });
  for (size_t j = 0; j < jobs.size(); ++j) {
    const Job& job = jobs[j];
    const bool rre = job.model == "rre";
    QualityRow& row = out.rows[j];
    row.model = job.model;
    row.components = job.K;
    std::vector<double> pooled;
    double mean_sum = 0, max_all = 0;
    for (size_t t = 0; t < test.size(); ++t) {
      const Eigen::VectorXd& e = errors[j][t];
      std::vector<double> ev(e.data(), e.data() + e.size());
      TestMeshError pm{job.model, names[t], job.K, e.mean(), percentile(ev, 95), e.maxCoeff(), seconds[j][t],
                       converged[j][t], starts[j][t].first, starts[j][t].second};
      row.unconverged_fits += converged[j][t] == 0;
      mean_sum += pm.mean_mm;
      max_all = std::max(max_all, pm.max_mm);
      pooled.insert(pooled.end(), ev.begin(), ev.end());
      out.per_mesh.push_back(pm);
    }
    row.generalisation_mean_mm = mean_sum / static_cast<double>(test.size());
    row.generalisation_p95_mm = percentile(pooled, 95);
    row.generalisation_max_mm = max_all;
    out.pooled_errors[j].assign(pooled.begin(), pooled.end());
    // Compactness.
    if (rre)
      row.compactness = pca.eigenvalues.head(job.K).sum() / rre_total;
    else
      row.compactness = vpca.pca.eigenvalues.head(job.K).sum() / vpca_total;
    // Specificity: samples c_k ~ N(0, λ_k), k < K, seeded per (model, K, sample).
    row.specificity_mean_mm = row.specificity_std_mm = std::numeric_limits<double>::quiet_NaN();
    const int max_k = rre ? pca.component_count() : vpca.pca.component_count();
    std::vector<int> spec_ks = o.specificity_components.empty() ? std::vector<int>{5, 20, max_k} : o.specificity_components;
    for (auto& k : spec_ks) k = std::min(k, max_k);
    const bool want_specificity = std::find(spec_ks.begin(), spec_ks.end(), job.K) != spec_ks.end();
    if (!train.empty() && o.specificity_samples > 0 && want_specificity) {
      std::vector<double> d(o.specificity_samples);
      const Eigen::VectorXd& lambda = rre ? pca.eigenvalues : vpca.pca.eigenvalues;
      tbb::parallel_for(0, o.specificity_samples, [&](int s) {
        std::mt19937_64 rng(o.seed * 1000003ULL + static_cast<uint64_t>(s) * 7919ULL + (rre ? 0 : 1) +
                            static_cast<uint64_t>(job.K) * 104729ULL);
        std::normal_distribution<double> normal(0, 1);
        Eigen::VectorXd c(job.K);
        for (int k = 0; k < job.K; ++k) c(k) = std::sqrt(std::max(0.0, lambda(k))) * normal(rng);
        const Eigen::MatrixX3d V =
            rre ? decoder.decode(model.encoding_of(pca.mean + pca.basis.leftCols(job.K) * c)) : vpca.mesh(c);
        d[s] = nearest_training_distance(V, train);
        if (s % 20 == 19) tick(1, fmt::format("{} K={} specificity", job.model, job.K));
      });
      const double mean = std::accumulate(d.begin(), d.end(), 0.0) / static_cast<double>(d.size());
      double var = 0;
      for (double v : d) var += (v - mean) * (v - mean);
      row.specificity_mean_mm = mean;
      row.specificity_std_mm = d.size() > 1 ? std::sqrt(var / static_cast<double>(d.size() - 1)) : 0.0;
      out.specificity_samples_mm[j] = std::move(d);
    }
  }
  report_progress(progress, 1.0, "done");
  return out;
}

std::vector<QualityRow> pool_model_quality(const std::vector<ModelQuality>& folds) {
  struct Acc {
    std::vector<double> means, spec, compact, pooled;
    double max = 0;
    int unconverged = 0;
  };
  std::map<std::pair<std::string, int>, Acc> acc;
  std::vector<std::pair<std::string, int>> order;
  for (const auto& f : folds) {
    for (size_t j = 0; j < f.rows.size(); ++j) {
      const auto key = std::make_pair(f.rows[j].model, f.rows[j].components);
      if (!acc.count(key)) order.push_back(key);
      Acc& a = acc[key];
      for (const auto& pm : f.per_mesh)
        if (pm.model == key.first && pm.components == key.second) a.means.push_back(pm.mean_mm);
      a.pooled.insert(a.pooled.end(), f.pooled_errors[j].begin(), f.pooled_errors[j].end());
      a.spec.insert(a.spec.end(), f.specificity_samples_mm[j].begin(), f.specificity_samples_mm[j].end());
      a.compact.push_back(f.rows[j].compactness);
      a.max = std::max(a.max, f.rows[j].generalisation_max_mm);
      a.unconverged += f.rows[j].unconverged_fits;
    }
  }
  std::stable_sort(order.begin(), order.end(), [](const auto& x, const auto& y) {
    return x.first != y.first ? x.first < y.first : x.second < y.second;  // "rre" before "vertex_pca"
  });
  std::vector<QualityRow> rows;
  for (const auto& key : order) {
    const Acc& a = acc[key];
    QualityRow r;
    r.model = key.first;
    r.components = key.second;
    auto mean = [](const std::vector<double>& v) {
      return v.empty() ? std::numeric_limits<double>::quiet_NaN()
                       : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
    };
    r.generalisation_mean_mm = mean(a.means);
    r.generalisation_p95_mm = percentile(a.pooled, 95);
    r.generalisation_max_mm = a.max;
    r.specificity_mean_mm = mean(a.spec);
    double var = 0;
    for (double v : a.spec) var += (v - r.specificity_mean_mm) * (v - r.specificity_mean_mm);
    r.specificity_std_mm = a.spec.size() > 1 ? std::sqrt(var / static_cast<double>(a.spec.size() - 1))
                                             : std::numeric_limits<double>::quiet_NaN();
    r.compactness = mean(a.compact);
    r.unconverged_fits = a.unconverged;
    rows.push_back(r);
  }
  return rows;
}

}  // namespace bodymodel
