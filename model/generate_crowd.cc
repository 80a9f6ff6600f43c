#include "model/generate_crowd.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <mutex>
#include <map>
#include <set>

#include "core/error.h"

namespace bodymodel {

namespace {

struct Fnv1a {
  uint64_t h = 1469598103934665603ull;
  void bytes(const void* p, size_t n) {
    const auto* c = static_cast<const unsigned char*>(p);
    for (size_t i = 0; i < n; ++i) h = (h ^ c[i]) * 1099511628211ull;
  }
  void strided(const double* p, size_t n, size_t stride) {
    for (size_t i = 0; i < n; i += stride) bytes(p + i, sizeof(double));
    bytes(&n, sizeof n);
  }
};

}  // namespace

std::string model_fingerprint(const BodyModel& model) {
  Fnv1a h;
  const SubModel& sm = model.shape;
  h.strided(sm.pca.eigenvalues.data(), sm.pca.eigenvalues.size(), 1);
  h.strided(sm.regression.gradients.data(), sm.regression.gradients.size(), 1);
  for (auto& l : sm.regression.labels) h.bytes(l.name.data(), l.name.size() + 1);
  h.strided(sm.pca.basis.data(), sm.pca.basis.size(), 1009);
  h.strided(sm.pca.mean.data(), sm.pca.mean.size(), 101);
  if (model.mean) h.strided(model.mean->values.data(), model.mean->values.size(), 101);
  const int64_t faces = model.tmpl ? model.tmpl->triangle_count() : 0;
  h.bytes(&faces, sizeof faces);
  return fmt::format("{:016x}", h.h);
}

void generate_crowd_bodies(std::shared_ptr<const BodyModel> model, const std::vector<LabelCondition>& conditions,
                           const std::vector<int>& indices, const GenerateCrowdOptions& o,
                           const std::function<void(CrowdBody&&)>& on_body, const ProgressCallback& progress) {
  generate_crowd_bodies_for(
      std::move(model), [&](int) { return conditions; }, indices, o, on_body, progress);
}

void generate_crowd_bodies_for(std::shared_ptr<const BodyModel> model,
                               const std::function<std::vector<LabelCondition>(int)>& conditions_of,
                               const std::vector<int>& indices, const GenerateCrowdOptions& o,
                               const std::function<void(CrowdBody&&)>& on_body, const ProgressCallback& progress) {
  if (o.threads < 0) throw InputError(fmt::format("generate: {} threads", o.threads));
  check_generate_options(o.generate);
  const ShapeMorpher morpher(model);
  // Calibrate each distinct label set and sex's measured response first, with every core (in
  // the loop below the first body to need one would calibrate it alone while other workers
  // wait for it).
  {
    std::set<std::string> prepared;
    auto prepare_all = [&] {
      for (int k : indices) {
        const std::vector<LabelCondition> c = conditions_of(k);
        std::string key;
        for (const auto& l : c) key += l.label + (l.label == "sex" ? fmt::format("={}|", l.lo) : "|");
        if (prepared.insert(key).second) prepare_generation(morpher, c, o.generate);
      }
    };
    if (o.threads > 0) {
      tbb::task_arena arena(o.threads);
      arena.execute(prepare_all);
    } else {
      prepare_all();
    }
  }
  std::mutex mutex;  // the progress callback is not assumed thread-safe
  int done = 0;
  const int n = static_cast<int>(indices.size());
  auto body = [&](int t) {
    CrowdBody b;
    b.index = indices[t];
    b.body = generate_body(morpher, conditions_of(b.index), crowd_body_seed(o.seed, b.index), o.generate);
    b.flipped_triangles = flipped_triangle_count(*model, b.body.V);
    on_body(std::move(b));
    std::lock_guard<std::mutex> lock(mutex);
    ++done;
    report_progress(progress, static_cast<double>(done) / n, fmt::format("body {}", indices[t]));
  };
  if (o.threads > 0) {
    tbb::task_arena arena(o.threads);
    arena.execute([&] { tbb::parallel_for(0, n, body); });
  } else {
    tbb::parallel_for(0, n, body);
  }
}

double mean_pairwise_distance(const std::vector<Eigen::MatrixX3d>& bodies) {
  std::vector<std::pair<int, int>> pairs;
  for (int i = 0; i < static_cast<int>(bodies.size()); ++i)
    for (int j = i + 1; j < static_cast<int>(bodies.size()); ++j) pairs.emplace_back(i, j);
  std::vector<double> d(pairs.size());
  tbb::parallel_for(0, static_cast<int>(pairs.size()),
                    [&](int p) { d[p] = rms_vertex_distance(bodies[pairs[p].first], bodies[pairs[p].second]); });
  double sum = 0;
  for (double v : d) sum += v;
  return pairs.empty() ? 0.0 : sum / static_cast<double>(pairs.size());
}

std::vector<int> diversity_subjects(const BodyModel& model, Sex sex, int sample) {
  const int sex_label = model.shape.regression.find("sex");
  std::vector<int> out;
  for (int i = 0; i < model.shape.pca.coefficients.rows(); ++i)
    if (static_cast<int>(out.size()) < sample &&
        (sex == Sex::unknown || sex_label < 0 ||
         std::abs(model.shape.labels(i, sex_label) - (sex == Sex::male ? 1.0 : 0.0)) < 0.5))
      out.push_back(i);
  return out;
}

namespace {

// The subjects `which` decoded from their coefficients, in parallel (`threads` 0 = all cores).
std::map<int, Eigen::MatrixX3d> decode_subjects(const BodyModel& model, const std::set<int>& which, int threads) {
  const auto shared = std::shared_ptr<const BodyModel>(std::shared_ptr<const BodyModel>(), &model);
  const ShapeMorpher morpher(shared);
  const std::vector<int> list(which.begin(), which.end());
  std::vector<Eigen::MatrixX3d> V(list.size());
  const auto& C = model.shape.pca.coefficients;
  auto run = [&] {
    tbb::parallel_for(0, static_cast<int>(list.size()), [&](int t) {
      V[t] = morpher.decode(morpher.reconstruct(C.row(list[t]).transpose()));
    });
  };
  if (threads > 0) {
    tbb::task_arena arena(threads);
    arena.execute(run);
  } else {
    run();
  }
  std::map<int, Eigen::MatrixX3d> out;
  for (size_t t = 0; t < list.size(); ++t) out.emplace(list[t], std::move(V[t]));
  return out;
}

SubjectDiversity diversity_of(const std::vector<int>& subjects, const std::map<int, Eigen::MatrixX3d>& decoded) {
  std::vector<Eigen::MatrixX3d> bodies;
  for (int i : subjects) bodies.push_back(decoded.at(i));
  return SubjectDiversity{mean_pairwise_distance(bodies), static_cast<int>(subjects.size())};
}

const char* sex_key(Sex sex) { return sex == Sex::female ? "female" : sex == Sex::male ? "male" : "unknown"; }

}  // namespace

SubjectDiversity subject_diversity(const BodyModel& model, Sex sex, int sample, int threads) {
  const std::vector<int> subjects = diversity_subjects(model, sex, sample);
  return diversity_of(subjects, decode_subjects(model, std::set<int>(subjects.begin(), subjects.end()), threads));
}

nlohmann::json subject_diversity_record(const BodyModel& model, int sample, int threads) {
  const Sex sexes[] = {Sex::unknown, Sex::female, Sex::male};
  std::set<int> all;
  for (Sex s : sexes)
    for (int i : diversity_subjects(model, s, sample)) all.insert(i);
  const std::map<int, Eigen::MatrixX3d> decoded = decode_subjects(model, all, threads);
  nlohmann::json record = {{"fingerprint", model_fingerprint(model)}, {"sample", sample}};
  for (Sex s : sexes) {
    const SubjectDiversity d = diversity_of(diversity_subjects(model, s, sample), decoded);
    record[sex_key(s)] = {{"mean_pairwise_mm", d.mean_pairwise_mm}, {"subjects", d.subjects}};
  }
  return record;
}

std::optional<SubjectDiversity> stored_subject_diversity(const BodyModel& model, Sex sex, int sample) {
  if (!model.metadata.is_object() || !model.metadata.contains("subject_diversity")) return std::nullopt;
  const nlohmann::json& r = model.metadata["subject_diversity"];
  if (!r.is_object() || r.value("sample", -1) != sample || !r.contains(sex_key(sex)) ||
      r.value("fingerprint", std::string()) != model_fingerprint(model))
    return std::nullopt;
  const nlohmann::json& e = r[sex_key(sex)];
  if (!e.is_object() || !e.contains("mean_pairwise_mm") || !e["mean_pairwise_mm"].is_number() ||
      !e.contains("subjects") || !e["subjects"].is_number_integer())
    return std::nullopt;
  return SubjectDiversity{e["mean_pairwise_mm"].get<double>(), e["subjects"].get<int>()};
}

}  // namespace bodymodel
