// People with recorded body measurements: an NHANES file ($BODYMODEL_DATA/anthropometry) or a
// people.csv of one's own, and the weighted sampling of a population from them.
//
// Columns (case-sensitive; NHANES names or ours, either works):
//   id                    SEQN | seqn | id            (missing: the row number)
//   sex                   RIAGENDR (1 male, 2 female) | sex (female|male|f|m)
//   age_years             RIDAGEYR | age_years        (NHANES tops coded ages at 80)
//   height_cm             BMXHT | height_cm
//   weight_kg             BMXWT | weight_kg
//   waist_iliac_cm        BMXWAIST | waist_iliac_cm   (NHANES waist is at the iliac crest)
//   hips_cm               BMXHIP | hips_cm
//   arm_circumference_cm  BMXARMC | arm_circumference_cm
//   upper_arm_length_cm   BMXARML | upper_arm_length_cm
//   upper_leg_length_cm   BMXLEG | upper_leg_length_cm
//   survey_weight         WTMECPRP | survey_weight    (persons each participant represents)
//   ethnicity             RIDRETH3 | ethnicity        (NHANES codes 1–7; a prior for MakeHuman's
//                                                      ethnic sliders, ethnic_prior())
// Lines starting with '#' are comments; fields may be double-quoted; NA or an empty field is a
// missing value. Other columns are ignored.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "core/measure.h"
#include "population/fit_measurements.h"

namespace bodymodel {

// The recorded measurements a person can have (fit-measurements' names), in this order.
const std::vector<std::string>& recorded_measurement_names();

struct Person {
  std::string id;       // SEQN, or the row number
  int line = 0;         // 1-based line in the file
  Sex sex = Sex::unknown;
  double age_years = std::numeric_limits<double>::quiet_NaN();
  double survey_weight = std::numeric_limits<double>::quiet_NaN();
  int ethnicity = 0;    // RIDRETH3 code, 0 = unknown
  // One value per recorded_measurement_names(), NaN when missing.
  std::vector<double> measurements = std::vector<double>(recorded_measurement_names().size(),
                                                         std::numeric_limits<double>::quiet_NaN());
  double measurement(const std::string& name) const;  // NaN when missing or unknown
};

struct PeopleTable {
  std::string source;                  // the file, for messages
  std::vector<Person> people;          // every data row
  std::vector<std::string> columns;    // our names of the columns found (sex, age_years, ...)
  bool has(const std::string& column) const;
};

// Reads a people file. Throws InputError naming the file and line for an unreadable file, no
// header, a row whose field count differs from the header's, a value that is not a number or a
// sex code that is neither 1/2 nor female/male.
PeopleTable read_people(const std::filesystem::path& path);

// Throws InputError naming the file and the missing columns (with their NHANES names) unless
// every one of `columns` (our names) is present.
void require_columns(const PeopleTable& table, const std::vector<std::string>& columns);

// MakeHuman ethnic prior (african, asian, caucasian) for an NHANES RIDRETH3 code: 3 (white)
// mostly caucasian, 4 (black) mostly african, 6 (Asian) mostly asian, 1–2 (Hispanic) a mix,
// anything else 1/3 each. A rough prior: MakeHuman's three ethnic targets are coarse.
std::array<double, 3> ethnic_prior(int ridreth3);

// Which people may be drawn: adults (unless allow_children) with a sex, an age and every
// `required` measurement, and a positive survey weight when `need_weight`.
struct PopulationFilter {
  bool allow_children = false;
  bool need_survey_weight = true;
  std::vector<std::string> required = {"height_cm", "weight_kg"};
};
struct EligibleSummary {
  std::vector<int> eligible;          // indices into table.people
  int children = 0, incomplete = 0, no_weight = 0;  // excluded, by reason
};
EligibleSummary eligible_people(const PeopleTable& table, const PopulationFilter& filter);

// Draws `count` people (indices into table.people, from `candidates`) with probability
// proportional to the survey weight: systematic PPS sampling with implicit stratification —
// candidates ordered by sex, then along a Hilbert curve over (height, weight) ranks, and picked
// at a random start plus multiples of total weight / count. Survey statistics' standard design:
// the sample's height and weight distributions per sex follow the weighted population much more
// closely than independent draws would (for 100 people, independent draws give a KS distance
// above 0.1 about a quarter of the time). A person whose weight exceeds the interval can be
// drawn twice. The result is shuffled (seeded), reproducible for a seed, and InputError when
// there are no candidates or count < 1.
std::vector<int> sample_population(const PeopleTable& table, const std::vector<int>& candidates, int count,
                                   uint64_t seed);

// The people of a table to fit one by one (`fit-measurements --people`): every row, checked.
// Each row needs a sex, an age and every `required` measurement; an incomplete row or an age
// under 18 (without allow_children) is an InputError naming the file and line, or, with
// skip_incomplete, skipped and counted. InputError too when no row is left.
struct PeopleSelection {
  std::vector<int> rows;           // indices into table.people
  int incomplete = 0, children = 0;  // rows skipped (skip_incomplete)
};
PeopleSelection select_people(const PeopleTable& table, const std::vector<std::string>& required,
                              bool allow_children, bool skip_incomplete);

// What fit_measurements needs for a person: sex, age, the ethnic prior and, as targets, the
// person's recorded values of `measurements` (those the person has).
PersonSpec person_spec(const Person& person, const std::vector<std::string>& measurements);

// Two-sample Kolmogorov–Smirnov statistic sup |F_a − F_b| between the values `a` (each weight 1)
// and the values `b` with weights `wb` (the weighted empirical distribution).
double ks_statistic(std::vector<double> a, const std::vector<double>& b, const std::vector<double>& wb);

}  // namespace bodymodel
