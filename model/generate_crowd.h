// The bodies of a crowd (`bodymodel generate`, Hasler et al. 2009 §5.2), generated in parallel
// and handed to the caller one by one; writing them (meshes, labels.csv, the settings, resuming
// an interrupted run) is the tools' job (tools/pipeline/crowd_output.h).
//
// DETERMINISM. Body k is generate_body(conditions, crowd_body_seed(seed, k)) (model/morph.h): it
// depends on the seed and k only, not on the number of threads, the order bodies finish in or
// the count (a crowd of 10 is the first 10 bodies of a crowd of 200 with the same seed).
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/progress.h"
#include "model/body_model.h"
#include "model/morph.h"

namespace bodymodel {

// Bumped whenever generate_body's algorithm changes what a seed produces (a resumed crowd must
// not mix bodies of two algorithms).
inline constexpr int kCrowdGeneratorVersion = 4;  // 3: fold repair after decoding; 4: quadratic measured response at the sex's mean

// The generation seed of body k of a crowd seeded with `seed`.
inline uint64_t crowd_body_seed(uint64_t seed, int k) { return seed * 1000003ull + static_cast<uint64_t>(k); }

struct GenerateCrowdOptions {
  GenerateOptions generate;   // per-body generation (model/morph.h)
  uint64_t seed = 1;          // the crowd is a function of it
  int threads = 0;            // bodies generated in parallel; 0 = all cores (TBB's default)
};

struct CrowdBody {
  int index = 0;              // k: the body's place in the crowd
  GeneratedBody body;
  int flipped_triangles = 0;  // after the fold repair (flipped_triangle_count)
};

// Content fingerprint of a model (hex): the shape model's eigenvalues, regression, labels and a
// sample of its basis and mean. Two loads of one file give the same fingerprint.
std::string model_fingerprint(const BodyModel& model);

// Generates the bodies `indices` of a crowd. `on_body` receives each body as soon as it is made,
// on the worker thread that made it (so concurrently and in any order: it must be thread-safe),
// and may keep or drop it, so a crowd of any size never has to fit in memory. Progress over
// `indices`. Throws InputError for a negative thread count or bad conditions.
void generate_crowd_bodies(std::shared_ptr<const BodyModel> model, const std::vector<LabelCondition>& conditions,
                           const std::vector<int>& indices, const GenerateCrowdOptions& options,
                           const std::function<void(CrowdBody&&)>& on_body, const ProgressCallback& progress = {});
// The same with conditions of their own per body (a population crowd: body k is morphed to
// person k's labels): `conditions_of(k)` gives body k's conditions (called once per body, from
// the worker threads: it must be thread-safe).
void generate_crowd_bodies_for(std::shared_ptr<const BodyModel> model,
                               const std::function<std::vector<LabelCondition>(int)>& conditions_of,
                               const std::vector<int>& indices, const GenerateCrowdOptions& options,
                               const std::function<void(CrowdBody&&)>& on_body,
                               const ProgressCallback& progress = {});

// ---- Diversity: how different a crowd's bodies are, against the model's training subjects ----

// How many training subjects (of the crowd's sex) `generate` compares a crowd's first bodies with.
inline constexpr int kDiversitySample = 40;

// Mean rms_vertex_distance (model/morph.h) over the pairs i < j of `bodies`, summed in that order
// (the pairs are measured in parallel; the sum does not depend on the thread count).
double mean_pairwise_distance(const std::vector<Eigen::MatrixX3d>& bodies);

// The training subjects a crowd of `sex` is compared with: the first `sample` shape-model
// subjects of that sex (of any sex for Sex::unknown or a model without a sex label).
std::vector<int> diversity_subjects(const BodyModel& model, Sex sex, int sample);

struct SubjectDiversity {
  double mean_pairwise_mm = 0;  // mean_pairwise_distance of the decoded subjects
  int subjects = 0;
};
// The diversity_subjects decoded from their shape coefficients (ShapeMorpher with the default
// decoder, as a crowd's bodies are), then mean_pairwise_distance. `threads` 0 = all cores.
SubjectDiversity subject_diversity(const BodyModel& model, Sex sex, int sample, int threads = 0);

// The same for Sex::unknown, female and male at once (each subject decoded once), as a record for
// the model's metadata["subject_diversity"] (`bodymodel build` stores it, so `generate` need not
// decode the subjects on every run): {"fingerprint": model_fingerprint, "sample", "unknown" |
// "female" | "male": {"mean_pairwise_mm", "subjects"}}.
nlohmann::json subject_diversity_record(const BodyModel& model, int sample, int threads = 0);
// The stored figure for `sex` and `sample` when the model's metadata has a record made for this
// very model (same fingerprint: bases, mean, eigenvalues, regression), else nullopt.
std::optional<SubjectDiversity> stored_subject_diversity(const BodyModel& model, Sex sex, int sample);

}  // namespace bodymodel
