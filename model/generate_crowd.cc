#include "model/generate_crowd.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <mutex>
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

}  // namespace bodymodel
