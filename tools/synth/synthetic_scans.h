// Synthetic scan database: MakeHuman bodies, posed, scanned by a simulated laser scanner.
//
// A stand-in for the laser-scan database of Hasler et al. 2009, with ground truth kept apart.
// Scanner model: four vertical pillars at the corners of a square around the subject (like a
// Vitus body scanner). Each pillar sweeps horizontally-aimed rays up and down: a surface point
// is seen by a pillar when the horizontal ray to it is unobstructed and hits the surface at
// less than `max_incidence_deg` from its normal. Points no pillar sees are holes (armpits,
// crotch, soles, the top of the head, ...). Seen points get Gaussian noise; normals are then
// estimated from the noisy points (PCA of neighbours) and oriented towards the pillar.
#pragma once

#include <Eigen/Core>
#include <random>
#include <string>
#include <vector>

#include "core/makehuman.h"
#include "core/mesh.h"
#include "core/progress.h"
#include "population/fit_measurements.h"

namespace bodymodel {

struct ScannerOptions {
  int pillars = 4;                   // evenly spaced around the subject, first at 45°
  double pillar_distance_mm = 1200;  // horizontal distance from the subject's axis
  double max_incidence_deg = 75;     // steeper (grazing) hits are not measured
  double noise_sigma_mm = 1.0;       // Gaussian noise per coordinate
  int min_points = 50000;            // at least this many seen points per scan
  double pixel_mm = 1.5;             // z-buffer resolution (vertical mm, horizontal mm at 1 m)
  int normal_neighbours = 16;        // k for PCA normal estimation
};

// Simulated scan of a mesh (V #V by 3 mm, F #F by 3). Points uniform by area on the seen surface.
PointCloud simulate_scan(const Eigen::MatrixX3d& V, const Eigen::MatrixX3i& F,
                         const ScannerOptions& options, std::mt19937_64& rng);

struct SyntheticDatabaseOptions {
  int subjects = 20;
  int poses_per_subject = 4;   // in addition to the standard A-pose
  unsigned seed = 1;
  double perturbation_deg = 4;   // σ of the random rotation added to each posed major joint
  double landmark_sigma_mm = 5;  // noise of the landmark positions
  double max_yaw_deg = 15;       // random turn of the subject on the scanner platform
  double max_shift_mm = 40;      // random horizontal placement on the platform
  ScannerOptions scanner;
  int threads = 0;               // 0 = all cores
  // Resume: when OUT/database.json describes this same database (every option above that changes
  // the output, and the pose pool), a scan whose four files (scans/<id>.ply, .landmarks.json,
  // truth/<id>.ply, .pose.csv) all exist and parse is kept and not made again; a scan with any
  // of them missing or unreadable is made again in full. Otherwise every scan is made (the
  // files of this database's scan ids are removed first, so a later resume never keeps a file
  // made with other options). Either way the folder ends byte-identical to a clean run.
  bool resume = true;
  // A real population instead of uniform sliders: a people file (population/people.h, e.g.
  // NHANES); `subjects` adults with sex, age and every `population_measurements` value are drawn
  // by survey weight (seeded, sample_population) and each subject's truth body is the MakeHuman
  // body fitted to the person's recorded measurements (fit_measurements, `fit`). Empty = the
  // uniform slider draw (random_makehuman_subject, core/makehuman.h).
  // ANSUR II files (population/ansur.h; one per sex, e.g. ansur2_female.csv,ansur2_male.csv) instead:
  // `subjects` soldiers drawn uniformly (alternating sexes when both files are given), each fitted
  // to `population_measurements` as ANSUR names them (population/ansur_fit.h) with the file's own
  // prior completing the others, every body modifier free.
  std::string population;
  std::vector<std::string> population_measurements = {"height_cm", "weight_kg", "waist_iliac_cm", "hips_cm",
                                                      "arm_circumference_cm"};
  FitMeasurementsOptions fit;
  // A fit-measurements batch's fit.csv whose bodies are reused: a drawn person listed there with
  // the same sex, age and fitted measurements gets that row's sliders and modifiers (stored to 4
  // decimals) instead of a new fit (seconds of CPU each). Empty = fit every person.
  std::string fits;
  // Write the truth meshes, poses and tables only, without simulating the scanner: what `build`
  // reads (it builds from truth/), for model studies where registration is not the question.
  bool truth_only = false;
};

// Checks the values of a fit-measurements fit.csv (SyntheticDatabaseOptions::fits) without
// MakeHuman's data: every slider_*, modifier_* and age_years cell a finite number in the range
// fit-measurements writes (macro sliders 0 … 1, weight up to FitMeasurementsOptions::weight_max,
// modifiers ±modifier_limit). InputError naming the file, line and column.
void check_stored_fits(const std::string& fits);

// What a subject is: slider values and measured labels (measured on the standard-pose mesh).
struct SyntheticSubject {
  std::string id;
  MacroSettings sliders;
  Eigen::VectorXd modifiers;  // MakeHuman's measurement modifiers (population subjects; empty = 0)
  Eigen::VectorXd shape_modifiers;  // MakeHuman's body-shape modifiers (ANSUR subjects; empty = 0)
  // ANSUR subjects: the survey's columns measured on the standard-pose truth mesh (labels named
  // as the survey names them, population/ansur_fit.h ansur_measurement_set()).
  std::vector<std::pair<std::string, double>> ansur_measured;
  // ANSUR subjects: the soldier's own recorded values of those columns (weightkg in kg), written to
  // subjects.csv as ansur2_<column>: labels a model study can regress against the real person.
  std::vector<std::pair<std::string, double>> ansur_recorded;
  bool extrapolated = false;  // sliders or modifiers beyond MakeHuman's range (extended space)
  std::string sex;  // "female" | "male" (gender slider < 0.5 | ≥ 0.5)
  double age_years = 0;
  double height_cm = 0, weight_kg = 0, body_fat_pct = 0, muscle = 0;
  double waist_cm = 0, hips_cm = 0, chest_cm = 0, neck_cm = 0;
  // Survey measurements of the truth mesh (core/measure.h).
  double waist_iliac_cm = 0, arm_circumference_cm = 0, upper_arm_length_cm = 0, upper_leg_length_cm = 0;
  // Population subjects: the person (SEQN), the recorded values (recorded_measurement_names(),
  // NaN = not recorded) and whether the fit reached every fitted measurement, else why not.
  std::string person_id;
  std::vector<double> recorded;
  bool fit_reached = true;
  std::string fit_reason;
};

struct SyntheticScanInfo {
  std::string id, subject_id, pose;
  int points = 0;
  double seen_fraction = 0;  // of the surface area
};

struct SyntheticDatabaseSummary {
  std::vector<SyntheticSubject> subjects;
  std::vector<SyntheticScanInfo> scans;
  std::vector<std::string> pose_pool;
  double seconds = 0;
  int skipped = 0;               // scans kept from an earlier run of the same database
  int removed_temporaries = 0;   // stale write_atomically temporaries of killed runs removed
  int eligible_people = 0;       // population: adults with every needed value and a weight
  double fit_seconds = 0;        // population: fitting the truth bodies
  int reused_fits = 0;           // population: bodies taken from SyntheticDatabaseOptions::fits
};

// What OUT/database.json would hold for these options (seed, sizes, scanner, noise, pose pool):
// the description of the database, and the key a resume compares.
std::string synthetic_database_description(const MakeHuman& makehuman,
                                           const SyntheticDatabaseOptions& options);

// Whether `out_dir`/database.json describes exactly the database `options` make. When it does not
// and `difference` is given, it receives a short phrase naming the first difference ("seed was
// 11, now 5", "no database.json", ...).
bool is_same_synthetic_database(const MakeHuman& makehuman, const std::string& out_dir,
                                const SyntheticDatabaseOptions& options,
                                std::string* difference = nullptr);

// Generates the whole database into `out_dir` (see tools/verbs/synth_db.cc for the layout).
SyntheticDatabaseSummary generate_synthetic_database(const MakeHuman& makehuman,
                                                     const std::string& out_dir,
                                                     const SyntheticDatabaseOptions& options,
                                                     const ProgressCallback& progress = {});

}  // namespace bodymodel
