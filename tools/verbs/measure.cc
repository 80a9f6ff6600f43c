// bodymodel measure mesh.obj [--sex female|male] [--json] [--unit mm|cm|dm|m]
#include <fmt/format.h>

#include <algorithm>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/io/json_text.h"
#include "core/io/mesh_io.h"
#include "core/makehuman.h"
#include "core/measure.h"
#include "core/survey_columns.h"
#include "tools/verb.h"

namespace bodymodel {
namespace {

struct MeasureArgs {
  std::string mesh;
  std::string sex = "unknown";
  std::string unit = "mm";
  bool json = false;
  std::string standard;  // "", "nhanes" or "ansur2": the survey's columns
};

// The ANSUR II columns of a template-topology body: its skeleton from the body's own vertices
// (MakeHuman::skeleton_from_body), the measurer's tubes from MakeHuman's default body.
std::vector<SurveyValue> ansur2_of(const Mesh& m, const std::string& what) {
  if (m.V.rows() != kSurveyTemplateVertexCount)
    throw InputError(what + ": --standard ansur2 needs a body with the hm08 template's topology (" +
                     std::to_string(kSurveyTemplateVertexCount) + " vertices, got " + std::to_string(m.V.rows()) +
                     "): a MakeHuman body, a registration or a model's output");
  const MakeHuman mh = MakeHuman::load();
  const MakeHuman::Body ref = mh.body(MacroSettings{});
  const AnsurMeasurer measurer(mh.body_faces(), mh.body_weights(), ref.mesh.V, ref.skeleton);
  return ansur2_columns(measurer, m.V, mh.skeleton_from_body(m.V), what);
}

void print_columns(const std::vector<SurveyValue>& cols, bool json) {
  if (json) {
    nlohmann::ordered_json j = nlohmann::ordered_json::object();
    for (const auto& c : cols) j[c.column] = c.value;
    fmt::print("{}\n", json_text(j, 2));
    return;
  }
  size_t width = 10;  // NHANES's names fit; ANSUR's are longer
  for (const auto& c : cols) width = std::max(width, c.column.size() + 2);
  for (const auto& c : cols) fmt::print("{:<{}}{:>8.1f}  {}, {}\n", c.column, width, c.value, c.unit, c.definition);
}

double unit_in_mm(const std::string& unit) {
  if (unit == "mm") return 1;
  if (unit == "cm") return 10;
  if (unit == "dm") return 100;
  if (unit == "m") return 1000;
  throw InputError("--unit must be one of mm, cm, dm, m (got '" + unit + "')");
}

}  // namespace

BODYMODEL_VERB(add_measure_verb) {
  auto args = std::make_shared<MeasureArgs>();
  auto* cmd = app.add_subcommand(
      "measure",
      "Measure a closed body mesh in the standard pose: height, volume, weight, girths, body fat.\n"
      "Girths are convex-hull perimeters of horizontal sections (see core/measure.h).");
  cmd->add_option("mesh", args->mesh, "Closed body mesh (OBJ or PLY), +y up")->required();
  cmd->add_option("--sex", args->sex, "female|male: needed for the body-fat formula (U.S. Navy)")
      ->check(CLI::IsMember({"unknown", "female", "male"}))
      ->capture_default_str();
  cmd->add_option("--unit", args->unit, "Unit of the mesh coordinates: mm, cm, dm or m")
      ->capture_default_str();
  cmd->add_flag("--json", args->json, "Print JSON instead of a table");
  cmd->add_option("--standard", args->standard,
                  "nhanes: the NHANES body-measure columns (BMXHT, BMXWT, BMXWAIST, BMXHIP, BMXARMC,\n"
                  "BMXARML, BMXLEG) as the survey defines them; ansur2: 23 ANSUR II columns (stature,\n"
                  "weightkg, chestcircumference, ... in mm, weightkg in kg; docs/measurements.md);\n"
                  "both on bodies with the template's topology")
      ->check(CLI::IsMember({"nhanes", "ansur2"}));
  cmd->callback([args] {
    Mesh m = read_mesh(args->mesh);
    if (args->standard == "ansur2") {
      m.V *= unit_in_mm(args->unit);
      print_columns(ansur2_of(m, "'" + args->mesh + "'"), args->json);
      return;
    }
    MeasureOptions o;
    o.mm_per_unit = unit_in_mm(args->unit);
    Sex sex = args->sex == "male" ? Sex::male : args->sex == "female" ? Sex::female : Sex::unknown;
    BodyMeasurements b;
    try {
      b = measure_body(m.V, m.F, sex, o);
    } catch (const InputError& e) {
      throw InputError("'" + args->mesh + "': " + e.what());
    }
    if (b.height_cm < 30 || b.height_cm > 300)
      fmt::print(stderr,
                 "bodymodel: warning: height {:.1f} cm is implausible for a body: is --unit {} "
                 "right?\n",
                 b.height_cm, args->unit);
    if (!args->standard.empty()) {
      print_columns(nhanes_columns(b, "'" + args->mesh + "'"), args->json);
      return;
    }
    if (args->json) {
      nlohmann::json j = {{"height_cm", b.height_cm}, {"volume_l", b.volume_l},
                          {"weight_kg", b.weight_kg}, {"density_kg_per_l", o.density_kg_per_l},
                          {"neck_cm", b.neck_cm},     {"chest_cm", b.chest_cm},
                          {"waist_cm", b.waist_cm},   {"hips_cm", b.hips_cm}};
      if (std::isfinite(b.body_fat_pct)) j["body_fat_pct"] = b.body_fat_pct;
      fmt::print("{}\n", json_text(j, 2));
      return;
    }
    fmt::print("{:<14}{:>10}  {}\n", "measurement", "value", "note");
    fmt::print("{:<14}{:>10.1f}  cm, extent along +y\n", "height", b.height_cm);
    fmt::print("{:<14}{:>10.1f}  L, divergence theorem\n", "volume", b.volume_l);
    fmt::print("{:<14}{:>10.1f}  kg, volume x {} kg/L\n", "weight", b.weight_kg, o.density_kg_per_l);
    fmt::print("{:<14}{:>10.1f}  cm, at {:.1f} cm\n", "neck girth", b.neck_cm, b.neck_at_cm);
    fmt::print("{:<14}{:>10.1f}  cm, at {:.1f} cm\n", "chest girth", b.chest_cm, b.chest_at_cm);
    fmt::print("{:<14}{:>10.1f}  cm, at {:.1f} cm\n", "waist girth", b.waist_cm, b.waist_at_cm);
    fmt::print("{:<14}{:>10.1f}  cm, at {:.1f} cm\n", "hips girth", b.hips_cm, b.hips_at_cm);
    if (std::isfinite(b.body_fat_pct))
      fmt::print("{:<14}{:>10.1f}  %, U.S. Navy formula ({})\n", "body fat", b.body_fat_pct, args->sex);
    else
      fmt::print("{:<14}{:>10}  give --sex for the U.S. Navy formula\n", "body fat", "-");
  });
}

}  // namespace bodymodel
