#include "population/people.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <numeric>
#include <random>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/csv.h"

namespace bodymodel {

namespace {

// Our column name for a header name (NHANES or ours), "" for columns we ignore.
std::string our_column(const std::string& h) {
  static const std::map<std::string, std::string> names = {
      {"SEQN", "id"},          {"seqn", "id"},           {"id", "id"},
      {"RIAGENDR", "sex"},     {"sex", "sex"},           {"RIDAGEYR", "age_years"},
      {"age_years", "age_years"}, {"BMXHT", "height_cm"}, {"height_cm", "height_cm"},
      {"BMXWT", "weight_kg"},  {"weight_kg", "weight_kg"}, {"BMXWAIST", "waist_iliac_cm"},
      {"waist_iliac_cm", "waist_iliac_cm"}, {"BMXHIP", "hips_cm"}, {"hips_cm", "hips_cm"},
      {"BMXARMC", "arm_circumference_cm"}, {"arm_circumference_cm", "arm_circumference_cm"},
      {"BMXARML", "upper_arm_length_cm"}, {"upper_arm_length_cm", "upper_arm_length_cm"},
      {"BMXLEG", "upper_leg_length_cm"}, {"upper_leg_length_cm", "upper_leg_length_cm"},
      {"WTMECPRP", "survey_weight"}, {"survey_weight", "survey_weight"},
      {"RIDRETH3", "ethnicity"}, {"ethnicity", "ethnicity"}};
  auto it = names.find(h);
  return it == names.end() ? "" : it->second;
}

std::string nhanes_name(const std::string& ours) {
  static const std::map<std::string, std::string> names = {
      {"sex", "RIAGENDR"}, {"age_years", "RIDAGEYR"}, {"height_cm", "BMXHT"}, {"weight_kg", "BMXWT"},
      {"waist_iliac_cm", "BMXWAIST"}, {"hips_cm", "BMXHIP"}, {"arm_circumference_cm", "BMXARMC"},
      {"upper_arm_length_cm", "BMXARML"}, {"upper_leg_length_cm", "BMXLEG"}, {"survey_weight", "WTMECPRP"},
      {"ethnicity", "RIDRETH3"}};
  auto it = names.find(ours);
  return it == names.end() ? ours : it->second;
}

// Cells of a record (core/io/csv.h), trimmed of leading spaces too ("1, 2" as written by hand).
std::vector<std::string> trimmed(std::vector<std::string> cells) {
  for (auto& s : cells) {
    while (!s.empty() && s.back() == ' ') s.pop_back();
    s.erase(0, s.find_first_not_of(' ') == std::string::npos ? s.size() : s.find_first_not_of(' '));
  }
  return cells;
}

bool missing(const std::string& s) { return s.empty() || s == "NA" || s == "na" || s == "NaN" || s == "."; }

// Hilbert curve index of (x, y) on a 2^order grid (the classic xy2d).
uint64_t hilbert_index(uint32_t x, uint32_t y, int order) {
  uint64_t d = 0;
  for (uint32_t s = 1u << (order - 1); s > 0; s >>= 1) {
    const uint32_t rx = (x & s) > 0, ry = (y & s) > 0;
    d += static_cast<uint64_t>(s) * s * ((3 * rx) ^ ry);
    if (ry == 0) {
      if (rx == 1) x = s - 1 - x, y = s - 1 - y;
      std::swap(x, y);
    }
  }
  return d;
}

}  // namespace

const std::vector<std::string>& recorded_measurement_names() {
  static const std::vector<std::string> names = {"height_cm", "weight_kg", "waist_iliac_cm", "hips_cm",
                                                 "arm_circumference_cm", "upper_arm_length_cm",
                                                 "upper_leg_length_cm"};
  return names;
}

double Person::measurement(const std::string& name) const {
  const auto& names = recorded_measurement_names();
  const auto it = std::find(names.begin(), names.end(), name);
  return it == names.end() ? std::numeric_limits<double>::quiet_NaN() : measurements[it - names.begin()];
}

bool PeopleTable::has(const std::string& column) const {
  return std::find(columns.begin(), columns.end(), column) != columns.end();
}

PeopleTable read_people(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw InputError(fmt::format("cannot open '{}'", path.string()));
  PeopleTable t;
  t.source = path.string();
  // The project's one CSV reader: quoted ids, a spreadsheet's byte-order mark, CRLF.
  const std::vector<CsvRecord> records = read_csv_file(path);
  std::vector<std::string> header_cols;  // our name per header column ("" = ignored)
  bool have_header = false;
  const auto& names = recorded_measurement_names();
  for (const CsvRecord& record : records) {
    const int line_no = record.line;
    if (!record.fields.empty() && !record.fields[0].empty() && record.fields[0][0] == '#') continue;
    const auto fields = trimmed(record.fields);
    if (!have_header) {
      have_header = true;
      for (const auto& h : fields) {
        const std::string c = our_column(h);
        if (!c.empty() && std::find(header_cols.begin(), header_cols.end(), c) != header_cols.end())
          throw InputError(fmt::format("'{}' line {}: two columns mean '{}' (e.g. {} and {})", t.source, line_no, c,
                                       nhanes_name(c), c));
        header_cols.push_back(c);
        if (!c.empty()) t.columns.push_back(c);
      }
      continue;
    }
    if (fields.size() != header_cols.size())
      throw InputError(fmt::format("'{}' line {}: {} fields, the header has {}", t.source, line_no, fields.size(),
                                   header_cols.size()));
    Person p;
    p.line = line_no;
    p.id = std::to_string(t.people.size() + 1);
    for (size_t c = 0; c < fields.size(); ++c) {
      const std::string& col = header_cols[c];
      const std::string& f = fields[c];
      if (col.empty() || missing(f)) continue;
      if (col == "id") {
        p.id = f;
        continue;
      }
      if (col == "sex") {
        if (f == "2" || f == "female" || f == "f" || f == "F") p.sex = Sex::female;
        else if (f == "1" || f == "male" || f == "m" || f == "M") p.sex = Sex::male;
        else
          throw InputError(fmt::format("'{}' line {}: sex '{}' (expected female/male, or RIAGENDR 1 = male, 2 = female)",
                                       t.source, line_no, f));
        continue;
      }
      char* end = nullptr;
      const double v = std::strtod(f.c_str(), &end);
      if (!end || *end != '\0' || !std::isfinite(v))
        throw InputError(fmt::format("'{}' line {}: {} '{}' is not a number", t.source, line_no, col, f));
      if (col == "age_years") p.age_years = v;
      else if (col == "survey_weight") p.survey_weight = v;
      else if (col == "ethnicity") p.ethnicity = static_cast<int>(v);
      else {
        const auto it = std::find(names.begin(), names.end(), col);
        if (it != names.end()) p.measurements[it - names.begin()] = v;
      }
    }
    t.people.push_back(std::move(p));
  }
  if (!have_header) throw InputError(fmt::format("'{}' has no header line (and no data)", t.source));
  if (t.people.empty()) throw InputError(fmt::format("'{}' has a header but no data rows", t.source));
  return t;
}

void require_columns(const PeopleTable& table, const std::vector<std::string>& columns) {
  std::vector<std::string> absent;
  for (const auto& c : columns)
    if (!table.has(c)) absent.push_back(nhanes_name(c) == c ? c : fmt::format("{} (or {})", nhanes_name(c), c));
  if (!absent.empty())
    throw InputError(fmt::format("'{}' has no {} column{}", table.source, fmt::join(absent, ", "),
                                 absent.size() > 1 ? "s" : ""));
}

std::array<double, 3> ethnic_prior(int code) {
  switch (code) {
    case 3: return {0.05, 0.05, 0.90};  // non-Hispanic White
    case 4: return {0.90, 0.05, 0.05};  // non-Hispanic Black
    case 6: return {0.05, 0.90, 0.05};  // non-Hispanic Asian
    case 1:
    case 2: return {0.15, 0.25, 0.60};  // Mexican American, other Hispanic
    default: return {1.0 / 3, 1.0 / 3, 1.0 / 3};
  }
}

EligibleSummary eligible_people(const PeopleTable& table, const PopulationFilter& f) {
  EligibleSummary s;
  for (size_t i = 0; i < table.people.size(); ++i) {
    const Person& p = table.people[i];
    bool complete = p.sex != Sex::unknown && std::isfinite(p.age_years);
    for (const auto& r : f.required) complete = complete && std::isfinite(p.measurement(r));
    if (!complete) {
      ++s.incomplete;
      continue;
    }
    if (!f.allow_children && p.age_years < 18) {
      ++s.children;
      continue;
    }
    if (f.need_survey_weight && !(p.survey_weight > 0)) {
      ++s.no_weight;
      continue;
    }
    s.eligible.push_back(static_cast<int>(i));
  }
  return s;
}

PeopleSelection select_people(const PeopleTable& table, const std::vector<std::string>& required,
                              bool allow_children, bool skip_incomplete) {
  PeopleSelection s;
  for (size_t i = 0; i < table.people.size(); ++i) {
    const Person& p = table.people[i];
    std::vector<std::string> absent;
    if (p.sex == Sex::unknown) absent.push_back("sex");
    if (!std::isfinite(p.age_years)) absent.push_back("age_years");
    for (const auto& r : required)
      if (!std::isfinite(p.measurement(r))) absent.push_back(r);
    if (!absent.empty()) {
      if (skip_incomplete) {
        ++s.incomplete;
        continue;
      }
      throw InputError(fmt::format("'{}' line {} (person {}): no {} (NA or empty; --skip-incomplete skips such rows)",
                                   table.source, p.line, p.id, fmt::join(absent, ", ")));
    }
    if (p.age_years < 18 && !allow_children) {
      if (skip_incomplete) {
        ++s.children;
        continue;
      }
      throw InputError(fmt::format("'{}' line {} (person {}): age {:g} is under 18; MakeHuman's children need "
                                   "--allow-children (or --skip-incomplete to skip them)",
                                   table.source, p.line, p.id, p.age_years));
    }
    s.rows.push_back(static_cast<int>(i));
  }
  if (s.rows.empty())
    throw InputError(fmt::format("'{}': no row has a sex, an age and {} ({} incomplete, {} under 18)", table.source,
                                 fmt::join(required, ", "), s.incomplete, s.children));
  return s;
}

PersonSpec person_spec(const Person& person, const std::vector<std::string>& measurements) {
  PersonSpec spec;
  spec.sex = person.sex;
  spec.age_years = person.age_years;
  spec.ethnic_prior = ethnic_prior(person.ethnicity);
  for (const auto& m : measurements) {
    const double v = person.measurement(m);
    if (std::isfinite(v)) spec.targets.push_back({m, v});
  }
  return spec;
}

std::vector<int> sample_population(const PeopleTable& table, const std::vector<int>& candidates, int count,
                                   uint64_t seed) {
  if (count < 1) throw InputError(fmt::format("cannot draw {} people (need at least 1)", count));
  if (candidates.empty()) throw InputError(fmt::format("'{}': no eligible person to draw from", table.source));
  std::mt19937_64 rng(seed);
  // Ranks of height and weight within each sex, on a 256 × 256 grid.
  constexpr int kOrder = 8;
  const double cells = 1 << kOrder;
  struct Key {
    int index;
    int sex;
    uint64_t hilbert;
    double tie;
  };
  std::vector<Key> keys;
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  for (int sex : {0, 1}) {
    std::vector<int> group;
    for (int i : candidates) {
      const Person& p = table.people[i];
      if ((p.sex == Sex::male ? 1 : 0) == sex) group.push_back(i);
    }
    const int n = static_cast<int>(group.size());
    auto rank_of = [&](const std::string& name) {
      std::vector<int> order(n);
      std::iota(order.begin(), order.end(), 0);
      std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
        return table.people[group[a]].measurement(name) < table.people[group[b]].measurement(name);
      });
      std::vector<uint32_t> rank(n);
      for (int r = 0; r < n; ++r) rank[order[r]] = static_cast<uint32_t>(std::min(cells - 1, std::floor(cells * r / n)));
      return rank;
    };
    const auto rh = rank_of("height_cm"), rw = rank_of("weight_kg");
    for (int k = 0; k < n; ++k) {
      const bool has = std::isfinite(table.people[group[k]].measurement("height_cm")) &&
                       std::isfinite(table.people[group[k]].measurement("weight_kg"));
      keys.push_back({group[k], sex, has ? hilbert_index(rh[k], rw[k], kOrder) : 0, u01(rng)});
    }
  }
  std::sort(keys.begin(), keys.end(), [](const Key& a, const Key& b) {
    return std::tie(a.sex, a.hilbert, a.tie) < std::tie(b.sex, b.hilbert, b.tie);
  });
  double total = 0;
  for (const Key& k : keys) {
    const double w = table.people[k.index].survey_weight;
    total += w > 0 ? w : 0;
  }
  // Without survey weights every candidate counts once.
  const bool weighted = total > 0;
  if (!weighted) total = static_cast<double>(keys.size());
  const double interval = total / count;
  double next = u01(rng) * interval, cumulative = 0;
  std::vector<int> chosen;
  for (const Key& k : keys) {
    const double w = weighted ? std::max(0.0, table.people[k.index].survey_weight) : 1.0;
    cumulative += w;
    while (next < cumulative && static_cast<int>(chosen.size()) < count) {
      chosen.push_back(k.index);
      next += interval;
    }
  }
  while (static_cast<int>(chosen.size()) < count) chosen.push_back(keys.back().index);  // rounding at the end
  std::shuffle(chosen.begin(), chosen.end(), rng);
  return chosen;
}

double ks_statistic(std::vector<double> a, const std::vector<double>& b, const std::vector<double>& wb) {
  if (a.empty() || b.empty() || b.size() != wb.size()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(a.begin(), a.end());
  std::vector<int> order(b.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int x, int y) { return b[x] < b[y]; });
  double wtotal = 0;
  for (double w : wb) wtotal += w;
  // Walk both sorted lists over the union of values.
  double d = 0, fa = 0, fb = 0;
  size_t i = 0, j = 0;
  while (i < a.size() || j < order.size()) {
    const double v = j >= order.size() || (i < a.size() && a[i] <= b[order[j]]) ? a[i] : b[order[j]];
    while (i < a.size() && a[i] <= v) ++i, fa = static_cast<double>(i) / a.size();
    while (j < order.size() && b[order[j]] <= v) fb += wb[order[j]] / wtotal, ++j;
    d = std::max(d, std::abs(fa - fb));
  }
  return d;
}

}  // namespace bodymodel
