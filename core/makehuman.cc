#include "core/makehuman.h"

#include <sys/stat.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <unordered_map>

#include "core/data_path.h"
#include "core/error.h"
#include "core/plausibility.h"
#include "core/point_index.h"

namespace bodymodel {
namespace fs = std::filesystem;

// ---- MacroSettings ---------------------------------------------------------------------------

namespace {
constexpr double kDmToMm = 100.0;

struct SliderRef {
  const char* key;
  double MacroSettings::*member;
};
constexpr std::array<SliderRef, 11> kSliders{{
    {"gender", &MacroSettings::gender},
    {"age", &MacroSettings::age},
    {"muscle", &MacroSettings::muscle},
    {"weight", &MacroSettings::weight},
    {"height", &MacroSettings::height},
    {"proportions", &MacroSettings::proportions},
    {"cup", &MacroSettings::cup},
    {"firmness", &MacroSettings::firmness},
    {"african", &MacroSettings::african},
    {"asian", &MacroSettings::asian},
    {"caucasian", &MacroSettings::caucasian},
}};
bool is_ethnic(std::string_view k) { return k == "african" || k == "asian" || k == "caucasian"; }
}  // namespace

MacroSettings MacroSettings::from_json(const nlohmann::json& j) {
  if (!j.is_object())
    throw InputError("macro settings: expected a JSON object, found " + j.dump());
  MacroSettings s;
  std::vector<std::string> ethnic_given;
  for (auto it = j.begin(); it != j.end(); ++it) {
    const SliderRef* ref = nullptr;
    for (const auto& r : kSliders)
      if (it.key() == r.key) ref = &r;
    if (!ref)
      throw InputError("macro settings: unknown key '" + it.key() +
                       "' (expected gender, age, muscle, weight, height, proportions, cup, "
                       "firmness, african, asian, caucasian)");
    if (!it.value().is_number())
      throw InputError("macro settings: '" + it.key() + "' must be a number, found " +
                       it.value().dump());
    s.*(ref->member) = it.value().get<double>();
    if (is_ethnic(it.key())) ethnic_given.push_back(it.key());
  }
  if (!ethnic_given.empty() && ethnic_given.size() < 3) {
    // The unspecified ethnic weights share what is left, in proportion to their defaults.
    double given = 0;
    for (const auto& k : ethnic_given)
      for (const auto& r : kSliders)
        if (k == r.key) given += s.*(r.member);
    const int rest = 3 - static_cast<int>(ethnic_given.size());
    for (const char* k : {"african", "asian", "caucasian"}) {
      if (std::find(ethnic_given.begin(), ethnic_given.end(), k) != ethnic_given.end()) continue;
      for (const auto& r : kSliders)
        if (std::string_view(k) == r.key) s.*(r.member) = std::max(0.0, 1.0 - given) / rest;
    }
  }
  s.validate();
  return s;
}

nlohmann::json MacroSettings::to_json() const {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& r : kSliders) j[r.key] = this->*(r.member);
  return j;
}

void MacroSettings::set_ethnic(const std::string& which, double value) {
  double* target = nullptr;
  std::vector<double*> others;
  for (auto [k, m] : {std::pair<const char*, double*>{"african", &african},
                      {"asian", &asian}, {"caucasian", &caucasian}}) {
    if (which == k) target = m;
    else others.push_back(m);
  }
  if (!target)
    throw InputError("unknown ethnic slider '" + which + "' (expected african, asian, caucasian)");
  if (!(value >= 0 && value <= 1))
    throw InputError("ethnic slider '" + which + "' must be in [0, 1], found " +
                     std::to_string(value));
  const double old_rest = *others[0] + *others[1];
  const double new_rest = 1.0 - value;
  *target = value;
  if (old_rest > 1e-12) {
    *others[0] *= new_rest / old_rest;
    *others[1] *= new_rest / old_rest;
  } else {
    *others[0] = *others[1] = new_rest / 2;
  }
}

double MacroSettings::age_years() const {
  return age < 0.5 ? 1.0 + 48.0 * age : 25.0 + 130.0 * (age - 0.5);
}

void MacroSettings::validate() const {
  for (const auto& r : kSliders) {
    const double v = this->*(r.member);
    if (!(v >= 0.0 && v <= 1.0))
      throw InputError(std::string("macro slider '") + r.key + "' must be in [0, 1], found " +
                       std::to_string(v));
  }
}

// ---- category values (README §5.2) ------------------------------------------------------------

namespace {

// Every category word that can occur in a macro target file name.
enum Category : int {
  kMale, kFemale, kBaby, kChild, kYoung, kOld,
  kMinMuscle, kAverageMuscle, kMaxMuscle,
  kMinWeight, kAverageWeight, kMaxWeight,
  kMinHeight, kAverageHeight, kMaxHeight,
  kUncommonProportions, kRegularProportions, kIdealProportions,
  kMinCup, kAverageCup, kMaxCup,
  kMinFirmness, kAverageFirmness, kMaxFirmness,
  kAfrican, kAsian, kCaucasian,
  kUniversal,  // group factor 1
  kCategoryCount
};
constexpr std::array<const char*, kCategoryCount> kCategoryNames{
    "male", "female", "baby", "child", "young", "old",
    "minmuscle", "averagemuscle", "maxmuscle",
    "minweight", "averageweight", "maxweight",
    "minheight", "averageheight", "maxheight",
    "uncommonproportions", "regularproportions", "idealproportions",
    "mincup", "averagecup", "maxcup",
    "minfirmness", "averagefirmness", "maxfirmness",
    "african", "asian", "caucasian", "universal"};

int category_of(std::string_view word) {
  for (int c = 0; c < kCategoryCount; ++c)
    if (word == kCategoryNames[c]) return c;
  return -1;
}

// min/average/max values of a three-way slider s.
void three_way(double s, double* out) {
  const double mx = std::max(0.0, 2 * s - 1), mn = std::max(0.0, 1 - 2 * s);
  out[0] = mn;
  out[1] = 1 - std::max(mx, mn);
  out[2] = mx;
}

std::array<double, kCategoryCount> category_values(const MacroSettings& s) {
  std::array<double, kCategoryCount> v{};
  v[kMale] = s.gender;
  v[kFemale] = 1 - s.gender;
  const double a = s.age;
  if (a < 0.5) {
    // MakeHuman's constants: 5.333 = 1/0.1875, 3.2 = 1/0.3125.
    v[kBaby] = std::max(0.0, 1 - a * 5.333);
    v[kYoung] = std::max(0.0, (a - 0.1875) * 3.2);
    v[kChild] = std::max(0.0, std::min(1.0, 5.333 * a) - v[kYoung]);
    v[kOld] = 0;
  } else {
    v[kOld] = 2 * a - 1;
    v[kYoung] = 1 - v[kOld];
    v[kBaby] = v[kChild] = 0;
  }
  three_way(s.muscle, &v[kMinMuscle]);
  three_way(s.weight, &v[kMinWeight]);
  three_way(s.height, &v[kMinHeight]);
  three_way(s.proportions, &v[kUncommonProportions]);
  three_way(s.cup, &v[kMinCup]);
  three_way(s.firmness, &v[kMinFirmness]);
  double ethnic_sum = s.african + s.asian + s.caucasian;
  if (ethnic_sum <= 0) ethnic_sum = 1;  // all zero: no ethnic targets at all
  v[kAfrican] = s.african / ethnic_sum;
  v[kAsian] = s.asian / ethnic_sum;
  v[kCaucasian] = s.caucasian / ethnic_sum;
  v[kUniversal] = 1;
  return v;
}

// ---- fast text parsing ----------------------------------------------------------------------

std::string read_whole_file(const fs::path& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw InputError("cannot open '" + path.string() + "': " + std::strerror(errno));
  std::string data;
  struct stat st {};
  if (::fstat(fileno(f), &st) == 0 && st.st_size > 0) data.reserve(st.st_size);
  char buf[1 << 16];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) data.append(buf, n);
  const bool bad = std::ferror(f);
  std::fclose(f);
  if (bad) throw InputError("cannot read '" + path.string() + "'");
  return data;
}

// Parses a plain decimal ("-.016", "12", "0.5") at p; exact (mantissa / 10^k is one correctly
// rounded division) and several times faster than strtod. Falls back to strtod for anything
// else (exponents, long mantissas, inf/nan).
inline double parse_decimal(const char* p, char** end) {
  const char* q = p;
  bool neg = false;
  if (*q == '-' || *q == '+') neg = *q++ == '-';
  uint64_t mant = 0;
  int digits = 0, frac = 0;
  while (*q >= '0' && *q <= '9') mant = mant * 10 + (*q++ - '0'), ++digits;
  if (*q == '.') {
    ++q;
    while (*q >= '0' && *q <= '9') mant = mant * 10 + (*q++ - '0'), ++digits, ++frac;
  }
  if (digits == 0 || digits > 18 || frac > 22 || *q == 'e' || *q == 'E')
    return std::strtod(p, end);
  static constexpr double kPow10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                        1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                        1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
  *end = const_cast<char*>(q);
  const double v = static_cast<double>(mant) / kPow10[frac];
  return neg ? -v : v;
}

struct Target {
  std::string name;               // relative to targets/, e.g. "macrodetails/height/x.target"
  std::vector<int> categories;    // category indices whose product is the weight
  int file = -1;                  // index into the distinct parsed files (as on disk)
  int data = -1;                  // index actually used (after substitution)
};

struct TargetData {
  std::vector<int> index;         // #n vertex indices
  std::vector<float> offset;      // #n*3 offsets, dm
};

// Parses a .target file: "# comment" lines and "<index> <dx> <dy> <dz>" lines.
// `text` must stay NUL-terminated (std::string): the number scanners stop at the terminator.
TargetData parse_target_text(const std::string& text, const std::string& name, int vertex_count) {
  TargetData t;
  t.index.reserve(text.size() / 24);
  t.offset.reserve(text.size() / 8);
  const char* p = text.c_str();
  const char* end = p + text.size();
  int line = 0;
  auto fail = [&](const std::string& what) {
    throw InputError("target '" + name + "' line " + std::to_string(line) + ": " + what);
  };
  while (p < end) {
    ++line;
    const char* eol = static_cast<const char*>(std::memchr(p, '\n', end - p));
    if (!eol) eol = end;
    const char* q = p;
    while (q < eol && (*q == ' ' || *q == '\t' || *q == '\r')) ++q;
    if (q == eol || *q == '#') {
      p = eol + 1;
      continue;
    }
    const char* next = q;
    long idx = 0;
    while (*next >= '0' && *next <= '9' && idx < (1L << 40)) idx = idx * 10 + (*next++ - '0');
    if (next == q || !(*next == ' ' || *next == '\t'))
      fail("expected '<vertex index> <dx> <dy> <dz>', found '" + std::string(q, eol) + "'");
    if (idx < 0 || idx >= vertex_count)
      fail("vertex index " + std::to_string(idx) + " exceeds the base mesh (" +
           std::to_string(vertex_count) + " vertices, indices 0.." +
           std::to_string(vertex_count - 1) + ")");
    q = next;
    float d[3];
    for (int k = 0; k < 3; ++k) {
      while (q < eol && (*q == ' ' || *q == '\t')) ++q;
      char* end_of_number = nullptr;
      const double v = q < eol ? parse_decimal(q, &end_of_number) : 0.0;
      next = end_of_number;
      if (q >= eol || next == q || next > eol || !std::isfinite(v))
        fail("expected 3 offsets after the vertex index, found '" + std::string(p, eol) + "'");
      d[k] = static_cast<float>(v);
      q = next;
    }
    while (q < eol && (*q == ' ' || *q == '\t' || *q == '\r')) ++q;
    if (q != eol) fail("unexpected text after the offsets: '" + std::string(q, eol) + "'");
    t.index.push_back(static_cast<int>(idx));
    t.offset.insert(t.offset.end(), d, d + 3);
    p = eol + 1;
  }
  return t;
}

TargetData parse_target(const fs::path& path, int vertex_count) {
  return parse_target_text(read_whole_file(path), path.string(), vertex_count);
}

// base.obj: vertices and the faces of group "body" (any other group's faces are skipped).
struct BaseMesh {
  Eigen::MatrixX3d V;                  // dm
  std::vector<std::array<int, 4>> body_quads;
  std::vector<std::array<int, 3>> body_tris;
};

BaseMesh parse_base_obj(const fs::path& path) {
  const std::string text = read_whole_file(path);
  std::vector<double> coords;
  coords.reserve(19158 * 3);
  BaseMesh mesh;
  bool in_body = false;
  const char* p = text.c_str();
  const char* end = p + text.size();
  int line = 0;
  auto fail = [&](const std::string& what) {
    throw InputError("base mesh '" + path.string() + "' line " + std::to_string(line) + ": " +
                     what);
  };
  std::vector<int> face;
  while (p < end) {
    ++line;
    const char* eol = static_cast<const char*>(std::memchr(p, '\n', end - p));
    if (!eol) eol = end;
    if (eol - p >= 2 && p[0] == 'v' && p[1] == ' ') {
      const char* q = p + 2;
      char* next;
      for (int k = 0; k < 3; ++k) {
        const double v = std::strtod(q, &next);
        if (next == q || next > eol || !std::isfinite(v))
          fail("expected 'v x y z', found '" + std::string(p, eol) + "'");
        coords.push_back(v);
        q = next;
      }
    } else if (eol - p >= 2 && p[0] == 'g' && p[1] == ' ') {
      std::string name(p + 2, eol);
      while (!name.empty() && (name.back() == ' ' || name.back() == '\r')) name.pop_back();
      in_body = name == "body";
    } else if (eol - p >= 2 && p[0] == 'f' && p[1] == ' ' && in_body) {
      face.clear();
      const char* q = p + 2;
      while (q < eol) {
        while (q < eol && *q == ' ') ++q;
        if (q >= eol || *q == '\r') break;
        char* next;
        const long idx = std::strtol(q, &next, 10);
        if (next == q) fail("expected a vertex index in '" + std::string(p, eol) + "'");
        face.push_back(static_cast<int>(idx) - 1);
        q = next;
        while (q < eol && *q != ' ') ++q;  // skip /vt
      }
      if (face.size() == 4) mesh.body_quads.push_back({face[0], face[1], face[2], face[3]});
      else if (face.size() == 3) mesh.body_tris.push_back({face[0], face[1], face[2]});
      else fail("expected a triangle or quad, found " + std::to_string(face.size()) + " vertices");
    }
    p = eol + 1;
  }
  const int nv = static_cast<int>(coords.size() / 3);
  if (nv != MakeHuman::kVertexCount)
    throw InputError("base mesh '" + path.string() + "': expected " +
                     std::to_string(MakeHuman::kVertexCount) + " vertices (hm08), found " +
                     std::to_string(nv));
  mesh.V.resize(nv, 3);
  for (int i = 0; i < nv; ++i)
    for (int k = 0; k < 3; ++k) mesh.V(i, k) = coords[3 * i + k];
  return mesh;
}

nlohmann::ordered_json parse_json_text(const std::string& text, const std::string& name) {
  try {
    return nlohmann::ordered_json::parse(text);
  } catch (const nlohmann::json::exception& e) {  // parse_error, or out_of_range (number overflow)
    throw InputError("'" + name + "' is not valid JSON: " + e.what());
  }
}

nlohmann::ordered_json read_json(const fs::path& path) {
  return parse_json_text(read_whole_file(path), path.string());
}

}  // namespace

// ---- the loaded model -----------------------------------------------------------------------

struct MakeHuman::Impl {
  fs::path dir;
  Eigen::MatrixX3d base_dm;               // 19158 by 3, dm
  Eigen::MatrixX3d base_mm;               // 19158 by 3, mm
  std::vector<Target> targets;            // 564 macro targets
  std::shared_ptr<const std::vector<TargetData>> data;  // distinct files, shared by copies
  std::vector<std::string> substituted;
  // Measurement modifiers: names and their decr / incr target data (own parse, not shared).
  std::vector<std::string> measure_names;
  std::shared_ptr<const std::vector<std::array<TargetData, 2>>> measure_data;
  Eigen::MatrixX3i body_faces;
  // Skeleton topology; joint positions = joint_regressor * V.
  std::vector<std::string> bone_names;
  std::vector<int> parents;
  std::vector<int> head_joint, tail_joint;
  Eigen::SparseMatrix<double, Eigen::RowMajor> joint_regressor;  // #joints by 19158
  SkinWeights weights_all, weights_body;
  // Joints from body vertices only, fitted on first use (shared by copies).
  struct LazyBodyRegressor {
    std::once_flag once;
    Eigen::SparseMatrix<double, Eigen::RowMajor> joints;  // #joints by 13380
  };
  std::shared_ptr<LazyBodyRegressor> body_regressor = std::make_shared<LazyBodyRegressor>();
  // Body-shape modifiers, read on first use (most verbs never need them).
  struct LazyShapeModifiers {
    std::once_flag once;
    std::vector<MakeHuman::ShapeModifier> modifiers;
    std::vector<std::array<TargetData, 2>> data;  // [min side, max side]; one-sided: [1] only
  };
  std::shared_ptr<LazyShapeModifiers> shape = std::make_shared<LazyShapeModifiers>();
};

namespace {

void apply_options(MakeHuman::Impl& m, const MakeHuman::Options& options);

void load_targets(MakeHuman::Impl& m, const MakeHuman::Options& options) {
  const fs::path root = m.dir / "targets";
  std::vector<fs::path> files;
  for (const char* sub : {"macrodetails", "macrodetails/height", "macrodetails/proportions",
                          "breast"}) {
    const fs::path d = root / sub;
    std::error_code ec;
    if (!fs::is_directory(d, ec))
      throw InputError("MakeHuman target folder '" + d.string() + "' is missing");
    std::vector<fs::path> here;
    for (const auto& e : fs::directory_iterator(d, ec))
      if (e.is_regular_file() && e.path().extension() == ".target") here.push_back(e.path());
    if (ec) throw InputError("cannot list '" + d.string() + "': " + ec.message());
    std::sort(here.begin(), here.end());
    files.insert(files.end(), here.begin(), here.end());
  }
  // Distinct files by (device, inode): the data set stores identical targets as hard links.
  std::map<std::pair<dev_t, ino_t>, int> by_inode;
  std::vector<fs::path> distinct;
  for (const auto& f : files) {
    Target t;
    t.name = fs::relative(f, root).generic_string();
    const std::string stem = f.stem().string();
    size_t start = 0;
    while (start <= stem.size()) {
      size_t dash = stem.find('-', start);
      if (dash == std::string::npos) dash = stem.size();
      const std::string word = stem.substr(start, dash - start);
      const int c = category_of(word);
      if (c < 0)
        throw InputError("target '" + f.string() + "': unknown category word '" + word +
                         "' in the file name (README §5.2)");
      if (c != kUniversal) t.categories.push_back(c);
      start = dash + 1;
    }
    struct stat st {};
    int id;
    if (::stat(f.c_str(), &st) == 0) {
      auto [it, fresh] = by_inode.emplace(std::make_pair(st.st_dev, st.st_ino),
                                          static_cast<int>(distinct.size()));
      if (fresh) distinct.push_back(f);
      id = it->second;
    } else {
      id = static_cast<int>(distinct.size());
      distinct.push_back(f);
    }
    t.file = t.data = id;
    m.targets.push_back(std::move(t));
  }
  auto data = std::make_shared<std::vector<TargetData>>(distinct.size());
  std::vector<std::string> errors(distinct.size());
  tbb::parallel_for(size_t(0), distinct.size(), [&](size_t i) {
    try {
      (*data)[i] = parse_target(distinct[i], MakeHuman::kVertexCount);
    } catch (const InputError& e) {
      errors[i] = e.what();
    }
  });
  for (const auto& e : errors)
    if (!e.empty()) throw InputError(e);
  m.data = std::move(data);
  apply_options(m, options);
}

// (Re)applies the options to the loaded targets (README §10.1 substitution).
void apply_options(MakeHuman::Impl& m, const MakeHuman::Options& options) {
  m.substituted.clear();
  for (auto& t : m.targets) t.data = t.file;
  if (options.substitute_defective_height_targets) {
    for (const char* g : {"male", "female"}) {
      const std::string bad = std::string("macrodetails/height/") + g +
                              "-old-maxmuscle-maxweight-minheight.target";
      const std::string good = std::string("macrodetails/height/") + g +
                               "-old-averagemuscle-maxweight-minheight.target";
      Target* tb = nullptr;
      const Target* tg = nullptr;
      for (auto& t : m.targets) {
        if (t.name == bad) tb = &t;
        if (t.name == good) tg = &t;
      }
      if (!tb || !tg) continue;
      if ((*m.data)[tb->file].index.size() * 4 < (*m.data)[tg->file].index.size()) {
        tb->data = tg->data;
        m.substituted.push_back(bad);
      }
    }
  }
}

// targets/measure/measure-<name>-{decr,incr}.target in measurement_modifiers.json order (or the
// sorted file names when that file is missing); nothing when the folder is missing.
void load_measure_targets(MakeHuman::Impl& m) {
  const fs::path dir = m.dir / "targets" / "measure";
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return;
  std::vector<std::string> names;
  const fs::path json = m.dir / "modifiers" / "measurement_modifiers.json";
  if (fs::is_regular_file(json, ec)) {
    const auto j = read_json(json);
    for (const auto& group : j)
      if (group.contains("modifiers"))
        for (const auto& mod : group["modifiers"])
          if (mod.contains("target") && mod["target"].is_string()) {
            std::string t = mod["target"].get<std::string>();
            if (t.rfind("measure-", 0) == 0) names.push_back(t.substr(8));
          }
  } else {
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      const std::string stem = e.path().stem().string();
      if (stem.rfind("measure-", 0) == 0 && stem.size() > 13 && stem.compare(stem.size() - 5, 5, "-incr") == 0)
        names.push_back(stem.substr(8, stem.size() - 13));
    }
    std::sort(names.begin(), names.end());
  }
  auto data = std::make_shared<std::vector<std::array<TargetData, 2>>>(names.size());
  std::vector<std::string> errors(2 * names.size());
  tbb::parallel_for(size_t(0), 2 * names.size(), [&](size_t k) {
    const fs::path f = dir / ("measure-" + names[k / 2] + (k % 2 ? "-incr" : "-decr") + ".target");
    try {
      (*data)[k / 2][k % 2] = parse_target(f, MakeHuman::kVertexCount);
    } catch (const InputError& e) {
      errors[k] = e.what();
    }
  });
  for (const auto& e : errors)
    if (!e.empty()) throw InputError(e);
  m.measure_names = std::move(names);
  m.measure_data = std::move(data);
}

// The body-shape modifiers (header comment) with their target files: groups of
// modeling_modifiers.json that shape the body (not the head, face or genitals) and
// bodyshapes_modifiers.json. A modifier whose files are missing is left out.
void load_shape_modifiers(const MakeHuman::Impl& m, std::vector<MakeHuman::ShapeModifier>& mods,
                          std::vector<std::array<TargetData, 2>>& data) {
  static const std::set<std::string> body_groups = {"armslegs", "torso", "hip", "stomach", "buttocks", "neck",
                                                    "pelvis", "bodyshapes"};
  std::error_code ec;
  std::vector<std::array<fs::path, 2>> files;
  for (const char* json_name : {"modeling_modifiers.json", "bodyshapes_modifiers.json"}) {
    const fs::path json = m.dir / "modifiers" / json_name;
    if (!fs::is_regular_file(json, ec)) continue;
    for (const auto& group : read_json(json)) {
      if (!group.contains("group") || !group["group"].is_string() || !group.contains("modifiers")) continue;
      const std::string g = group["group"].get<std::string>();
      if (!body_groups.count(g)) continue;
      for (const auto& mod : group["modifiers"]) {
        if (!mod.contains("target") || !mod["target"].is_string()) continue;
        const std::string t = mod["target"].get<std::string>();
        MakeHuman::ShapeModifier sm;
        sm.group = g;
        std::array<fs::path, 2> f;
        if (mod.contains("min") && mod.contains("max") && mod["min"].is_string() && mod["max"].is_string()) {
          const std::string lo = mod["min"].get<std::string>(), hi = mod["max"].get<std::string>();
          sm.name = g + "/" + t + "-" + lo + "|" + hi;
          f = {m.dir / "targets" / g / (t + "-" + lo + ".target"), m.dir / "targets" / g / (t + "-" + hi + ".target")};
        } else {
          sm.two_sided = false;
          sm.name = g + "/" + t;
          f = {fs::path(), m.dir / "targets" / g / (t + ".target")};
        }
        if ((sm.two_sided && !fs::is_regular_file(f[0], ec)) || !fs::is_regular_file(f[1], ec)) continue;
        if (t.rfind("l-", 0) == 0 || t.rfind("r-", 0) == 0) sm.side = t.substr(0, 1);
        mods.push_back(std::move(sm));
        files.push_back(std::move(f));
      }
    }
  }
  for (size_t a = 0; a < mods.size(); ++a) {
    if (mods[a].side.empty()) continue;
    const std::string other = mods[a].group + "/" + (mods[a].side == "l" ? "r" : "l") +
                              mods[a].name.substr(mods[a].group.size() + 2);
    for (size_t b = 0; b < mods.size(); ++b)
      if (mods[b].name == other) mods[a].mirror = static_cast<int>(b);
  }
  data.resize(mods.size());
  std::vector<std::string> errors(2 * mods.size());
  tbb::parallel_for(size_t(0), 2 * mods.size(), [&](size_t k) {
    if (files[k / 2][k % 2].empty()) return;
    try {
      data[k / 2][k % 2] = parse_target(files[k / 2][k % 2], MakeHuman::kVertexCount);
    } catch (const InputError& e) {
      errors[k] = e.what();
    }
  });
  for (const auto& e : errors)
    if (!e.empty()) throw InputError(e);
}

void load_skeleton_json(MakeHuman::Impl& m, const nlohmann::ordered_json& j,
                        const fs::path& path) {
  auto fail = [&](const std::string& what) {
    throw InputError("skeleton '" + path.string() + "': " + what);
  };
  if (!j.contains("bones") || !j["bones"].is_object() || !j.contains("joints") ||
      !j["joints"].is_object())
    fail("expected objects 'bones' and 'joints'");
  // Joints.
  std::unordered_map<std::string, int> joint_index;
  std::vector<Eigen::Triplet<double>> trip;
  int nj = 0;
  for (auto it = j["joints"].begin(); it != j["joints"].end(); ++it) {
    const auto& list = it.value();
    if (!list.is_array() || list.empty()) fail("joint '" + it.key() + "' has no vertex list");
    for (const auto& v : list) {
      if (!v.is_number_integer()) fail("joint '" + it.key() + "' lists a non-integer vertex");
      const int vi = v.get<int>();
      if (vi < 0 || vi >= MakeHuman::kVertexCount)
        fail("joint '" + it.key() + "' lists vertex " + std::to_string(vi) +
             ", outside the base mesh (19158 vertices)");
      trip.emplace_back(nj, vi, 1.0 / static_cast<double>(list.size()));
    }
    joint_index[it.key()] = nj++;
  }
  m.joint_regressor.resize(nj, MakeHuman::kVertexCount);
  m.joint_regressor.setFromTriplets(trip.begin(), trip.end());
  // Bones in breadth-first order from the root (children in file order).
  struct RawBone {
    std::string name, parent;
    int head, tail;
  };
  std::vector<RawBone> raw;
  for (auto it = j["bones"].begin(); it != j["bones"].end(); ++it) {
    const auto& b = it.value();
    RawBone r;
    r.name = it.key();
    r.parent = b.contains("parent") && b["parent"].is_string() ? b["parent"].get<std::string>()
                                                              : "";
    for (auto [field, out] : {std::pair<const char*, int*>{"head", &r.head}, {"tail", &r.tail}}) {
      if (!b.contains(field) || !b[field].is_string())
        fail("bone '" + r.name + "' has no '" + field + "' joint");
      auto jt = joint_index.find(b[field].get<std::string>());
      if (jt == joint_index.end())
        fail("bone '" + r.name + "' refers to the unknown joint '" + b[field].get<std::string>() +
             "'");
      *out = jt->second;
    }
    raw.push_back(std::move(r));
  }
  std::unordered_map<std::string, int> order;
  std::vector<int> queue;
  for (int i = 0; i < static_cast<int>(raw.size()); ++i)
    if (raw[i].parent.empty()) queue.push_back(i);
  if (queue.size() != 1) fail("expected one root bone, found " + std::to_string(queue.size()));
  for (size_t q = 0; q < queue.size(); ++q) {
    const RawBone& r = raw[queue[q]];
    order[r.name] = static_cast<int>(q);
    m.bone_names.push_back(r.name);
    m.parents.push_back(r.parent.empty() ? -1 : order.at(r.parent));
    m.head_joint.push_back(r.head);
    m.tail_joint.push_back(r.tail);
    for (int i = 0; i < static_cast<int>(raw.size()); ++i)
      if (raw[i].parent == r.name) queue.push_back(i);
  }
  if (queue.size() != raw.size())
    fail(std::to_string(raw.size() - queue.size()) +
         " bones are not connected to the root (unknown parent)");
}

void load_skeleton(MakeHuman::Impl& m) {
  const fs::path path = m.dir / "rig" / "default.mhskel";
  load_skeleton_json(m, read_json(path), path);
}

void load_weights_json(MakeHuman::Impl& m, const nlohmann::ordered_json& j,
                       const fs::path& path) {
  if (!j.contains("weights") || !j["weights"].is_object())
    throw InputError("weights '" + path.string() + "': expected an object 'weights'");
  std::unordered_map<std::string, int> bone;
  for (int b = 0; b < static_cast<int>(m.bone_names.size()); ++b) bone[m.bone_names[b]] = b;
  const int nv = MakeHuman::kVertexCount, nb = static_cast<int>(m.bone_names.size());
  std::vector<Eigen::Triplet<double>> trip;
  for (auto it = j["weights"].begin(); it != j["weights"].end(); ++it) {
    auto bt = bone.find(it.key());
    if (bt == bone.end())
      throw InputError("weights '" + path.string() + "': bone '" + it.key() +
                       "' is not in the default skeleton");
    for (const auto& pair : it.value()) {
      if (!pair.is_array() || pair.size() != 2 || !pair[0].is_number_integer() ||
          !pair[1].is_number())
        throw InputError("weights '" + path.string() + "': bone '" + it.key() +
                         "' has an entry that is not [vertex, weight]: " + pair.dump());
      const int v = pair[0].get<int>();
      if (v < 0 || v >= nv)
        throw InputError("weights '" + path.string() + "': bone '" + it.key() + "' lists vertex " +
                         std::to_string(v) + ", outside the base mesh (19158 vertices)");
      trip.emplace_back(v, bt->second, pair[1].get<double>());
    }
  }
  SkinWeights W(nv, nb);
  W.setFromTriplets(trip.begin(), trip.end());  // sums duplicate (vertex, bone) pairs
  // Normalise, drop < 1e-4, renormalise; unweighted vertices go to the root.
  std::vector<Eigen::Triplet<double>> out;
  out.reserve(W.nonZeros());
  for (int v = 0; v < nv; ++v) {
    double sum = 0;
    for (SkinWeights::InnerIterator it(W, v); it; ++it) sum += std::max(0.0, it.value());
    std::vector<std::pair<int, double>> row;
    if (sum > 0)
      for (SkinWeights::InnerIterator it(W, v); it; ++it) {
        const double w = std::max(0.0, it.value()) / sum;
        if (w >= 1e-4) row.emplace_back(static_cast<int>(it.col()), w);
      }
    double kept = 0;
    for (auto& [b, w] : row) kept += w;
    if (row.empty()) {
      out.emplace_back(v, 0, 1.0);
      continue;
    }
    for (auto& [b, w] : row) out.emplace_back(v, b, w / kept);
  }
  m.weights_all.resize(nv, nb);
  m.weights_all.setFromTriplets(out.begin(), out.end());
  m.weights_all.makeCompressed();
  m.weights_body = m.weights_all.topRows(MakeHuman::kBodyVertexCount);
  m.weights_body.makeCompressed();
}

void load_weights(MakeHuman::Impl& m) {
  const fs::path path = m.dir / "rig" / "default_weights.mhw";
  load_weights_json(m, read_json(path), path);
}

}  // namespace

// ---- parse-only entry points (tests, fuzzing) -------------------------------------------------

int parse_makehuman_target(const std::string& text, const std::string& name, int vertex_count) {
  return static_cast<int>(parse_target_text(text, name, vertex_count).index.size());
}

std::vector<std::string> parse_makehuman_skeleton(const std::string& text,
                                                  const std::string& name) {
  MakeHuman::Impl m;
  load_skeleton_json(m, parse_json_text(text, name), name);
  return m.bone_names;
}

SkinWeights parse_makehuman_weights(const std::string& text, const std::string& name,
                                    const std::vector<std::string>& bone_names) {
  MakeHuman::Impl m;
  m.bone_names = bone_names;
  load_weights_json(m, parse_json_text(text, name), name);
  return m.weights_all;
}

MakeHuman MakeHuman::load(const fs::path& makehuman_dir, const Options& options) {
  auto m = std::make_shared<Impl>();
  m->dir = makehuman_dir;
  std::error_code ec;
  if (!fs::is_directory(makehuman_dir, ec))
    throw InputError("MakeHuman folder '" + makehuman_dir.string() +
                     "' does not exist or is not readable");
  BaseMesh base = parse_base_obj(makehuman_dir / "base" / "base.obj");
  m->base_dm = std::move(base.V);
  m->base_mm = m->base_dm * kDmToMm;
  const int nf = static_cast<int>(2 * base.body_quads.size() + base.body_tris.size());
  m->body_faces.resize(nf, 3);
  int f = 0;
  for (const auto& q : base.body_quads) {
    m->body_faces.row(f++) << q[0], q[1], q[2];
    m->body_faces.row(f++) << q[0], q[2], q[3];
  }
  for (const auto& t : base.body_tris) m->body_faces.row(f++) << t[0], t[1], t[2];
  if (nf == 0 || m->body_faces.maxCoeff() >= kBodyVertexCount || m->body_faces.minCoeff() < 0)
    throw InputError("base mesh '" + (makehuman_dir / "base" / "base.obj").string() +
                     "': group 'body' must use exactly vertices 0.." +
                     std::to_string(kBodyVertexCount - 1));
  load_targets(*m, options);
  load_measure_targets(*m);
  load_skeleton(*m);
  load_weights(*m);
  MakeHuman mh;
  mh.impl_ = std::move(m);
  return mh;
}

MakeHuman MakeHuman::with_options(const Options& options) const {
  auto m = std::make_shared<Impl>(*impl_);  // target data is shared, not copied
  apply_options(*m, options);
  MakeHuman mh;
  mh.impl_ = std::move(m);
  return mh;
}

MakeHuman MakeHuman::load(const fs::path& makehuman_dir) { return load(makehuman_dir, Options{}); }
MakeHuman MakeHuman::load() { return load(data_file("makehuman"), Options{}); }

std::vector<std::pair<std::string, double>> MakeHuman::target_weights(
    const MacroSettings& settings) const {
  settings.validate();
  const auto values = category_values(settings);
  std::vector<std::pair<std::string, double>> out;
  for (const auto& t : impl_->targets) {
    double w = 1;
    for (int c : t.categories) w *= values[c];
    if (w != 0) out.emplace_back(t.name, w);
  }
  return out;
}

namespace {

void add_target(Eigen::MatrixX3d& V, const TargetData& d, double w) {
  double* x = V.col(0).data();
  double* y = V.col(1).data();
  double* z = V.col(2).data();
  const size_t n = d.index.size();
  const int* idx = d.index.data();
  const float* off = d.offset.data();
  for (size_t k = 0; k < n; ++k) {
    const int i = idx[k];
    x[i] += w * off[3 * k];
    y[i] += w * off[3 * k + 1];
    z[i] += w * off[3 * k + 2];
  }
}

}  // namespace

Eigen::MatrixX3d MakeHuman::build_vertices(const MacroSettings& settings) const {
  return build_vertices(settings, Eigen::VectorXd(), BuildOptions{});
}

Eigen::MatrixX3d MakeHuman::build_vertices(const MacroSettings& settings, const Eigen::VectorXd& modifiers,
                                           const BuildOptions& options) const {
  if (!options.allow_extrapolation) {
    settings.validate();
  } else {
    for (double v : {settings.gender, settings.age, settings.muscle, settings.weight, settings.height,
                     settings.proportions, settings.cup, settings.firmness})
      if (!std::isfinite(v)) throw InputError("macro slider is not finite");
    for (double v : {settings.gender, settings.african, settings.asian, settings.caucasian})
      if (!(v >= 0 && v <= 1))
        throw InputError("gender and the ethnic sliders must stay in [0, 1], found " + std::to_string(v));
  }
  const int nm = static_cast<int>(impl_->measure_names.size());
  if (modifiers.size() != 0 && modifiers.size() != nm)
    throw InputError("expected " + std::to_string(nm) + " measurement modifier values, found " +
                     std::to_string(modifiers.size()));
  for (Eigen::Index k = 0; k < modifiers.size(); ++k)
    if (!std::isfinite(modifiers(k)) || (!options.allow_extrapolation && std::abs(modifiers(k)) > 1))
      throw InputError("measurement modifier '" + impl_->measure_names[k] + "' must be in [-1, 1], found " +
                       std::to_string(modifiers(k)));
  const auto values = category_values(settings);
  Eigen::MatrixX3d V = impl_->base_dm;
  for (const auto& t : impl_->targets) {
    double w = 1;
    for (int c : t.categories) w *= values[c];
    if (w == 0) continue;
    add_target(V, (*impl_->data)[t.data], w);
  }
  for (Eigen::Index k = 0; k < modifiers.size(); ++k)
    if (modifiers(k) != 0) add_target(V, (*impl_->measure_data)[k][modifiers(k) > 0 ? 1 : 0], std::abs(modifiers(k)));
  V *= kDmToMm;
  return V;
}

const std::vector<std::string>& MakeHuman::measure_modifier_names() const { return impl_->measure_names; }

int MakeHuman::measure_modifier_index(const std::string& name) const {
  for (size_t k = 0; k < impl_->measure_names.size(); ++k)
    if (impl_->measure_names[k] == name) return static_cast<int>(k);
  return -1;
}

Eigen::MatrixX3d MakeHuman::measure_modifier_offsets(int modifier, bool increase) const {
  if (modifier < 0 || modifier >= static_cast<int>(impl_->measure_names.size()))
    throw InputError("measurement modifier index " + std::to_string(modifier) + " out of range");
  Eigen::MatrixX3d D = Eigen::MatrixX3d::Zero(kVertexCount, 3);
  add_target(D, (*impl_->measure_data)[modifier][increase ? 1 : 0], 1.0);
  return D * kDmToMm;
}

const std::vector<MakeHuman::ShapeModifier>& MakeHuman::shape_modifiers() const {
  auto& lazy = *impl_->shape;
  std::call_once(lazy.once, [&] { load_shape_modifiers(*impl_, lazy.modifiers, lazy.data); });
  return lazy.modifiers;
}

int MakeHuman::shape_modifier_index(const std::string& name) const {
  const auto& mods = shape_modifiers();
  for (size_t k = 0; k < mods.size(); ++k)
    if (mods[k].name == name) return static_cast<int>(k);
  return -1;
}

void MakeHuman::add_shape_modifier(Eigen::MatrixX3d& V, int k, double value) const {
  const auto& mods = shape_modifiers();
  if (k < 0 || k >= static_cast<int>(mods.size()))
    throw InputError("shape modifier index " + std::to_string(k) + " out of range");
  if (value == 0) return;
  if (!mods[k].two_sided && value < 0)
    throw InputError("shape modifier '" + mods[k].name + "' is one-sided: its value must be >= 0");
  const TargetData& d = impl_->shape->data[k][value > 0 ? 1 : 0];
  const double w = std::abs(value) * kDmToMm;
  const Eigen::Index rows = V.rows();
  for (size_t i = 0; i < d.index.size(); ++i) {
    const int v = d.index[i];
    if (v >= rows) continue;
    V(v, 0) += w * d.offset[3 * i];
    V(v, 1) += w * d.offset[3 * i + 1];
    V(v, 2) += w * d.offset[3 * i + 2];
  }
}

Eigen::MatrixX3d MakeHuman::build_vertices(const MacroSettings& settings, const Eigen::VectorXd& modifiers,
                                           const Eigen::VectorXd& shape, const BuildOptions& options) const {
  Eigen::MatrixX3d V = build_vertices(settings, modifiers, options);
  if (shape.size() == 0) return V;
  const auto& mods = shape_modifiers();
  if (shape.size() != static_cast<Eigen::Index>(mods.size()))
    throw InputError("expected " + std::to_string(mods.size()) + " shape modifier values, found " +
                     std::to_string(shape.size()));
  for (Eigen::Index k = 0; k < shape.size(); ++k) {
    const double lo = mods[k].two_sided ? -1.0 : 0.0;
    if (!std::isfinite(shape(k)) || (!options.allow_extrapolation && (shape(k) < lo || shape(k) > 1)) ||
        (!mods[k].two_sided && shape(k) < 0))
      throw InputError("shape modifier '" + mods[k].name + "' must be in [" + (mods[k].two_sided ? "-1" : "0") +
                       ", 1], found " + std::to_string(shape(k)));
  }
  for (Eigen::Index k = 0; k < shape.size(); ++k) add_shape_modifier(V, static_cast<int>(k), shape(k));
  return V;
}

const Eigen::MatrixX3d& MakeHuman::base_vertices() const { return impl_->base_mm; }
int MakeHuman::target_count() const { return static_cast<int>(impl_->targets.size()); }
std::vector<std::string> MakeHuman::substituted_targets() const { return impl_->substituted; }
const Eigen::MatrixX3i& MakeHuman::body_faces() const { return impl_->body_faces; }
const SkinWeights& MakeHuman::body_weights() const { return impl_->weights_body; }
const SkinWeights& MakeHuman::weights() const { return impl_->weights_all; }
const fs::path& MakeHuman::directory() const { return impl_->dir; }

Skeleton MakeHuman::skeleton(const Eigen::MatrixX3d& full_vertices) const {
  if (full_vertices.rows() != kVertexCount)
    throw InputError("MakeHuman skeleton: expected all " + std::to_string(kVertexCount) +
                     " hm08 vertices, found " + std::to_string(full_vertices.rows()));
  const Eigen::MatrixX3d J = impl_->joint_regressor * full_vertices;
  Skeleton s;
  s.names = impl_->bone_names;
  s.parents = impl_->parents;
  const int nb = static_cast<int>(s.names.size());
  s.heads.resize(nb, 3);
  s.tails.resize(nb, 3);
  for (int b = 0; b < nb; ++b) {
    s.heads.row(b) = J.row(impl_->head_joint[b]);
    s.tails.row(b) = J.row(impl_->tail_joint[b]);
  }
  return s;
}

namespace {

// Fits, for every joint, weights on body vertices around it (summing to one, so the result
// moves rigidly with the mesh) that reproduce the joint over random MakeHuman bodies:
//   min_w Σ_s ‖(X_s − j_s 1ᵀ) w‖² + λ ‖w − w0‖²   subject to Σ w = 1,
// X_s = the 128 candidate vertices of body s (the 16 nearest in each octant around the joint
// on the default body), j_s its joint, w0 inverse-distance weights. The macro targets move the
// surface but not the inner joints with weight and muscle (a fat belly leaves spine01 where it
// was), so an exact fit needs large cancelling weights that would amplify vertex noise on a
// registered mesh. λ = 1e-3 · trace/128 trades that off: ‖w‖₂ ≤ 2.3 (1 mm of vertex noise
// gives ≤ 2.3 mm of joint noise) for joint errors that are small on average and largest at
// the chest joints of extreme bodies (makehuman_test;
// docs/benchmarks.md#figures-behind-code-comments). Joints defined by body vertices alone are
// copied exactly.
Eigen::SparseMatrix<double, Eigen::RowMajor> fit_body_joint_regressor(const MakeHuman& mh,
                                                                      const MakeHuman::Impl& m) {
  constexpr int kSamples = 160, kCandidates = 128;
  const int nb = MakeHuman::kBodyVertexCount;
  std::mt19937 rng(20240611);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<MacroSettings> settings(kSamples);
  for (int k = 0; k < kSamples; ++k) {
    MacroSettings& s = settings[k];
    if (k > 0) {  // sample 0 is the default human
      for (double* v : {&s.gender, &s.age, &s.muscle, &s.weight, &s.height, &s.proportions,
                        &s.cup, &s.firmness})
        *v = u(rng);
      const double a = u(rng) + 1e-3, b = u(rng) + 1e-3, c = u(rng) + 1e-3;
      s.african = a / (a + b + c), s.asian = b / (a + b + c), s.caucasian = 1 - s.african - s.asian;
    }
  }
  std::vector<Eigen::MatrixX3d> bodies(kSamples), joints(kSamples);
  tbb::parallel_for(0, kSamples, [&](int k) {
    bodies[k] = mh.build_vertices(settings[k]);
    joints[k] = m.joint_regressor * bodies[k];
  });
  const PointIndex index(bodies[0].topRows(nb));
  const int nj = static_cast<int>(m.joint_regressor.rows());
  std::vector<std::vector<Eigen::Triplet<double>>> rows(nj);
  tbb::parallel_for(0, nj, [&](int j) {
    bool body_only = true;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(m.joint_regressor, j); it; ++it)
      body_only &= it.col() < nb;
    if (body_only) {
      for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(m.joint_regressor, j); it; ++it)
        rows[j].emplace_back(j, static_cast<int>(it.col()), it.value());
      return;
    }
    // Candidates surround the joint: the 4 nearest body vertices in each octant around it
    // (a one-sided patch cannot reach the inside of the trunk).
    const Eigen::Vector3d centre = joints[0].row(j).transpose();
    std::vector<double> near_d2;
    const std::vector<int> near = index.knn(centre, 3000, &near_d2);
    std::vector<int> cand;
    std::vector<double> d2;
    int per_octant[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    for (size_t c = 0; c < near.size(); ++c) {
      const Eigen::Vector3d d = bodies[0].row(near[c]).transpose() - centre;
      const int o = (d.x() > 0) + 2 * (d.y() > 0) + 4 * (d.z() > 0);
      if (per_octant[o] >= kCandidates / 8) continue;
      ++per_octant[o];
      cand.push_back(near[c]);
      d2.push_back(near_d2[c]);
    }
    const int k = static_cast<int>(cand.size());
    // With Σw = 1, X w − j = (X − j 1ᵀ) w: stack the relative positions of all samples.
    Eigen::MatrixXd X(3 * kSamples, k);
    for (int s = 0; s < kSamples; ++s)
      for (int c = 0; c < k; ++c)
        X.block<3, 1>(3 * s, c) = (bodies[s].row(cand[c]) - joints[s].row(j)).transpose();
    Eigen::MatrixXd AtA = Eigen::MatrixXd::Zero(k, k);
    AtA.selfadjointView<Eigen::Lower>().rankUpdate(X.transpose());
    AtA = AtA.selfadjointView<Eigen::Lower>();
    const Eigen::VectorXd Atb = Eigen::VectorXd::Zero(k);
    Eigen::VectorXd w0(k);
    for (int c = 0; c < k; ++c) w0[c] = 1.0 / (std::sqrt(d2[c]) + 1.0);
    w0 /= w0.sum();
    const double lambda = 1e-3 * AtA.trace() / k;
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(k + 1, k + 1);
    K.topLeftCorner(k, k) = 2 * (AtA + lambda * Eigen::MatrixXd::Identity(k, k));
    K.block(0, k, k, 1).setOnes();
    K.block(k, 0, 1, k).setOnes();
    Eigen::VectorXd rhs(k + 1);
    rhs.head(k) = 2 * (Atb + lambda * w0);
    rhs[k] = 1;
    const Eigen::VectorXd sol = K.fullPivLu().solve(rhs);
    for (int c = 0; c < k; ++c)
      if (sol[c] != 0) rows[j].emplace_back(j, cand[c], sol[c]);
  });
  std::vector<Eigen::Triplet<double>> all;
  for (auto& r : rows) all.insert(all.end(), r.begin(), r.end());
  Eigen::SparseMatrix<double, Eigen::RowMajor> R(nj, nb);
  R.setFromTriplets(all.begin(), all.end());
  return R;
}

}  // namespace

const Eigen::SparseMatrix<double, Eigen::RowMajor>& MakeHuman::body_joint_regressor() const {
  auto& lazy = *impl_->body_regressor;
  std::call_once(lazy.once, [&] { lazy.joints = fit_body_joint_regressor(*this, *impl_); });
  return lazy.joints;
}

Skeleton MakeHuman::skeleton_from_body(const Eigen::MatrixX3d& body_vertices) const {
  if (body_vertices.rows() != kBodyVertexCount)
    throw InputError("MakeHuman skeleton_from_body: expected the " +
                     std::to_string(kBodyVertexCount) + " body vertices, found " +
                     std::to_string(body_vertices.rows()));
  const Eigen::MatrixX3d J = body_joint_regressor() * body_vertices;
  Skeleton s;
  s.names = impl_->bone_names;
  s.parents = impl_->parents;
  const int nb = static_cast<int>(s.names.size());
  s.heads.resize(nb, 3);
  s.tails.resize(nb, 3);
  for (int b = 0; b < nb; ++b) {
    s.heads.row(b) = J.row(impl_->head_joint[b]);
    s.tails.row(b) = J.row(impl_->tail_joint[b]);
  }
  return s;
}

std::vector<char> MakeHuman::trunk_and_limbs_region() const {
  return bodymodel::trunk_and_limbs_region(impl_->bone_names, impl_->parents, impl_->weights_body);
}

MakeHuman::Body MakeHuman::body(const MacroSettings& settings) const {
  return body(settings, Eigen::VectorXd(), BuildOptions{});
}

MakeHuman::Body MakeHuman::body(const MacroSettings& settings, const Eigen::VectorXd& modifiers,
                                const BuildOptions& options) const {
  return body(settings, modifiers, Eigen::VectorXd(), options);
}

MakeHuman::Body MakeHuman::body(const MacroSettings& settings, const Eigen::VectorXd& modifiers,
                                const Eigen::VectorXd& shape_modifiers, const BuildOptions& options) const {
  const Eigen::MatrixX3d V = build_vertices(settings, modifiers, shape_modifiers, options);
  Body b;
  b.mesh.V = V.topRows(kBodyVertexCount);
  b.mesh.F = impl_->body_faces;
  b.skeleton = skeleton(V);
  b.weights = impl_->weights_body;
  return b;
}

std::vector<std::string> MakeHuman::pose_names() const {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(impl_->dir / "motion" / "poses", ec))
    if (e.path().extension() == ".bvh") names.push_back(e.path().stem().string());
  std::sort(names.begin(), names.end());
  return names;
}

fs::path MakeHuman::pose_file(const std::string& name) const {
  const fs::path p = impl_->dir / "motion" / "poses" / (name + ".bvh");
  std::error_code ec;
  if (!fs::is_regular_file(p, ec)) {
    std::string known;
    for (const auto& n : pose_names()) known += (known.empty() ? "" : ", ") + n;
    throw InputError("unknown pose '" + name + "' (known: " + known + ")");
  }
  return p;
}

double makehuman_body_height(const Eigen::MatrixX3d& V) {
  if (V.rows() < MakeHuman::kBodyVertexCount)
    throw InputError("makehuman_body_height: expected at least 13380 vertices, found " +
                     std::to_string(V.rows()));
  const auto y = V.col(1).head(MakeHuman::kBodyVertexCount);
  return y.maxCoeff() - y.minCoeff();
}

}  // namespace bodymodel
