// A crowd of random bodies written to a folder (`bodymodel generate`; the bodies come from
// model/generate_crowd.h): OUT/body_NNN.obj|ply, OUT/labels.csv with the MEASURED labels of
// every body (girths, survey measurements, roughness p95/max and self-intersecting triangle
// pairs, core/plausibility.h; for a population crowd also the person's id and recorded
// values), and OUT/generate.json with the settings the crowd was made with.
//
// RESUME. A rerun into the same folder with the same settings (generate.json equal: model
// fingerprint, seed, conditions, spread, attempts, girths, format, generator version) skips
// every body that is already complete — its mesh exists (meshes are written atomically, so an
// existing file is complete) and labels.csv has its row — and generates the rest; the result is
// byte-identical to a clean run. labels.csv is rewritten atomically (temporary + rename) every
// `labels_flush_seconds` during the run and at the end, with the rows of the bodies finished so
// far, so an interrupted run leaves a consistent labels.csv for the rerun to continue from.
// A folder holding a crowd made with OTHER settings is refused (InputError) unless `force`,
// which regenerates every body.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/progress.h"
#include "model/generate_crowd.h"

namespace bodymodel {

// One person of a population crowd (`generate --population`): body k is morphed to people[k]'s
// conditions and labels.csv keeps the person's recorded values beside the measured ones.
struct CrowdPerson {
  std::string id;                        // SEQN
  std::string sex;                       // female | male
  std::vector<LabelCondition> conditions;
  std::vector<double> recorded;          // population/people.h recorded_measurement_names(), NaN = none
};

struct CrowdOutputOptions {
  GenerateCrowdOptions crowd;  // what the bodies are (seed, per-body generation, threads)
  // A population crowd: one person per body (count == people.size()); empty = every body has the
  // `conditions` given to write_crowd.
  std::vector<CrowdPerson> people;
  std::string population_source;   // the people file (recorded in generate.json)
  std::vector<std::string> recorded_names;  // names of CrowdPerson::recorded (labels.csv nhanes_*)
  // Trunk-and-limbs region for the roughness columns (core/plausibility.h; #V entries or empty =
  // every vertex), e.g. from the model's rig.
  std::vector<char> roughness_region;
  std::string format = "obj";  // mesh format: obj or ply
  bool force = false;          // replace a crowd made with other settings instead of refusing
  bool resume = true;          // skip complete bodies of a crowd made with the same settings
  double labels_flush_seconds = 2.0;  // labels.csv is rewritten at most this often mid-run
};

struct GenerateCrowdSummary {
  int count = 0;
  int generated = 0;          // bodies made by this run
  int skipped = 0;            // complete bodies found from an earlier run (same settings)
  int constraints_met = 0;    // bodies meeting every condition as measured (of count)
  int flipped_triangles = 0;  // total over the crowd after the fold repair (flipped_triangle_count)
  int max_flipped_triangles = 0;    // ... of the worst body
  std::vector<int> flipped_before_repair;  // per body, as decoded (labels.csv flipped_before_repair)
  std::vector<int> self_intersections;     // per body (labels.csv self_intersections)
  std::vector<double> roughness_p95;       // per body, degrees
  double seconds = 0;         // wall time of the generation (set-up excluded)
  std::vector<std::string> files;  // count mesh file names (relative to the folder)
};

// Generates bodies 0..count-1 into `out` (created if missing). Throws InputError for a folder
// holding a crowd with other settings (unless options.force), an unwritable folder or bad
// conditions. Progress over the bodies to generate.
GenerateCrowdSummary write_crowd(std::shared_ptr<const BodyModel> model,
                                 const std::vector<LabelCondition>& conditions, int count,
                                 const std::filesystem::path& out, const CrowdOutputOptions& options = {},
                                 const ProgressCallback& progress = {});

}  // namespace bodymodel
