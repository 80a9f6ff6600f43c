#include "model/body_regions.h"

#include "core/error.h"
#include "model/format.h"

namespace bodymodel {

std::vector<std::string> body_region_names() {
  return {"arms", "legs", "torso", "head", "left_arm", "right_arm", "left_leg", "right_leg"};
}

namespace {

bool contains(const std::string& s, const char* part) { return s.find(part) != std::string::npos; }

bool bone_in_region(const std::string& b, const std::string& region) {
  const bool arm = contains(b, "arm") || contains(b, "hand") || contains(b, "finger") ||
                   contains(b, "metacarpal") || contains(b, "wrist") || contains(b, "shoulder") ||
                   contains(b, "clavicle");
  const bool leg = contains(b, "leg") || contains(b, "foot") || contains(b, "toe");
  const bool head = contains(b, "head") || contains(b, "neck") || contains(b, "jaw") ||
                    contains(b, "eye") || contains(b, "tongue") || contains(b, "teeth") ||
                    contains(b, "ear") || contains(b, "nose") || contains(b, "lip") ||
                    contains(b, "cheek") || contains(b, "brow") || contains(b, "chin") ||
                    contains(b, "temple") || contains(b, "levator") || contains(b, "oris") ||
                    contains(b, "risorius") || contains(b, "special");
  const bool left = b.size() > 2 && b.compare(b.size() - 2, 2, ".L") == 0;
  const bool right = b.size() > 2 && b.compare(b.size() - 2, 2, ".R") == 0;
  if (region == "arms") return arm;
  if (region == "legs") return leg;
  if (region == "head") return head && !arm;
  if (region == "torso") return !arm && !leg && !head;
  if (region == "left_arm") return arm && left;
  if (region == "right_arm") return arm && right;
  if (region == "left_leg") return leg && left;
  if (region == "right_leg") return leg && right;
  return false;
}

}  // namespace

Eigen::VectorXd body_region_vertex_mask(const ModelRig& rig, const std::string& region) {
  auto names = body_region_names();
  if (std::find(names.begin(), names.end(), region) == names.end()) {
    std::string list;
    for (auto& n : names) list += (list.empty() ? "" : ", ") + n;
    throw InputError(fmt::format("unknown body region '{}'; regions are: {}", region, list));
  }
  if (rig.empty()) throw InputError("body-region masks need the model's skeleton, and this model has none");
  Eigen::VectorXd sel(rig.bone_count());
  for (int b = 0; b < rig.bone_count(); ++b) sel(b) = bone_in_region(rig.bone_names[b], region) ? 1 : 0;
  Eigen::VectorXd m = rig.weights * sel;
  return m.cwiseMax(0.0).cwiseMin(1.0);
}

}  // namespace bodymodel
