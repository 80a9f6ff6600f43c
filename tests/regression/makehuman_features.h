// Realistic regression features without the model stage: random MakeHuman bodies (sampled like
// `bodymodel synth-db`), measured with measure_body, then a vertex-position PCA (through the
// #bodies × #bodies Gram matrix) whose per-body coefficients are the features. Shared by the
// regression tests and bench/regression_bench.cc. Nothing here is written to disk.
#pragma once

#include <Eigen/Dense>
#include <random>
#include <string>
#include <vector>

#include <tbb/parallel_for.h>

#include "core/random_subject.h"
#include "core/makehuman.h"
#include "core/measure.h"

namespace bodymodel {

struct MakeHumanFeatures {
  Eigen::MatrixXd coefficients;  // #bodies by #components: PCA coefficients (mm), largest first
  Eigen::VectorXd eigenvalues;   // #components, mm²
  Eigen::MatrixXd labels;        // #bodies by 5: height_cm, weight_kg, body_fat_pct, muscle, waist_cm
  std::vector<std::string> label_names{"height_cm", "weight_kg", "body_fat_pct", "muscle", "waist_cm"};
  std::vector<std::string> label_units{"cm", "kg", "%", "%", "cm"};
};

// `bodies` random subjects (half male), deterministic for a seed. vertex_noise_mm > 0 adds
// independent Gaussian noise of that σ to every vertex coordinate before the PCA (a stand-in for
// scanning and registration noise; labels are measured on the clean bodies).
inline MakeHumanFeatures make_makehuman_features(const MakeHuman& mh, int bodies, unsigned seed = 1,
                                                 double vertex_noise_mm = 0) {
  std::mt19937_64 rng(seed);
  std::vector<MacroSettings> settings;
  for (int i = 0; i < bodies; ++i) settings.push_back(random_makehuman_subject(rng, i % 2 == 0));
  const int nv = MakeHuman::kBodyVertexCount;
  Eigen::MatrixXd data(bodies, 3 * nv);
  MakeHumanFeatures out;
  out.labels.resize(bodies, 5);
  tbb::parallel_for(0, bodies, [&](int i) {
    const MakeHuman::Body body = mh.body(settings[i]);
    const bool male = settings[i].gender >= 0.5;
    const BodyMeasurements m = measure_body(body.mesh.V, body.mesh.F, male ? Sex::male : Sex::female);
    out.labels.row(i) << m.height_cm, m.weight_kg, m.body_fat_pct, settings[i].muscle * 100, m.waist_cm;
    std::mt19937_64 noise_rng(seed * 7919u + static_cast<unsigned>(i));
    std::normal_distribution<double> noise(0, vertex_noise_mm > 0 ? vertex_noise_mm : 1);
    for (int v = 0; v < nv; ++v)
      for (int k = 0; k < 3; ++k)
        data(i, 3 * v + k) = body.mesh.V(v, k) + (vertex_noise_mm > 0 ? noise(noise_rng) : 0.0);
  });
  const Eigen::MatrixXd centred = data.rowwise() - data.colwise().mean();
  const Eigen::MatrixXd gram = centred * centred.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(gram);
  int keep = 0;
  const double top = eig.eigenvalues().maxCoeff();
  for (int k = 0; k < bodies; ++k) keep += eig.eigenvalues()(k) > 1e-9 * top;
  out.coefficients.resize(bodies, keep);
  out.eigenvalues.resize(keep);
  for (int k = 0; k < keep; ++k) {
    const int src = bodies - 1 - k;  // eigenvalues ascend
    const double lambda = eig.eigenvalues()(src);
    out.coefficients.col(k) = eig.eigenvectors().col(src) * std::sqrt(lambda);  // = centred · unit axis
    out.eigenvalues(k) = lambda / std::max(1, bodies - 1);
  }
  return out;
}

}  // namespace bodymodel
