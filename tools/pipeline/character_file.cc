#include "tools/pipeline/character_file.h"

#include <unistd.h>

#include "core/error.h"
#include "core/io/json_text.h"
#include "core/io/npz.h"
#include "skinning/rig_io.h"

namespace bodymodel {

namespace fs = std::filesystem;

void save_character_rig(const fs::path& path, const CharacterRigFile& c) {
  // The rig keys through rig_io (one definition of them), then the extra keys.
  const fs::path tmp = path.parent_path() / (".rig-" + std::to_string(::getpid()) + ".npz");
  struct Remove {
    fs::path p;
    ~Remove() {
      std::error_code ec;
      fs::remove(p, ec);
    }
  } remove{tmp};
  save_rig(tmp, c.rig, c.F, c.training_transforms);
  Npz z = Npz::load(tmp);
  const Skeleton& s = c.skeleton;
  z.put_text("skeleton_names", json_text(nlohmann::json(s.names)));
  Eigen::VectorXi parents(s.bone_count());
  for (int b = 0; b < s.bone_count(); ++b) parents(b) = s.parents[b];
  z.put("skeleton_parents", parents);
  Eigen::VectorXi driven(s.bone_count());
  for (int b = 0; b < s.bone_count(); ++b) driven(b) = b < static_cast<int>(c.driven.size()) ? c.driven[b] : 1;
  z.put("skeleton_driven", driven);
  z.put("skeleton_heads", Eigen::MatrixXd(s.heads));
  z.put("skeleton_tails", Eigen::MatrixXd(s.tails));
  z.put("lbs_influences", c.lbs.influences);
  z.put("lbs_coefficients", c.lbs.coefficients);
  z.put("template_influences", c.template_lbs.influences);
  z.put("template_coefficients", c.template_lbs.coefficients);
  z.put_text("character", json_text(c.character));
  z.save(path);
}

CharacterRigFile load_character_rig(const fs::path& path) {
  CharacterRigFile c;
  c.rig = load_rig(path, &c.F, &c.training_transforms);
  const Npz z = Npz::load(path);
  if (!z.has("skeleton_names"))
    throw InputError(path.string() + ": no skeleton (key 'skeleton_names'): not a character rig from "
                     "`bodymodel character`");
  try {
    c.skeleton.names = nlohmann::json::parse(z.text("skeleton_names")).get<std::vector<std::string>>();
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path.string() + ": 'skeleton_names' is not a JSON list of names: " + e.what());
  }
  Eigen::VectorXi parents = z.int_vector("skeleton_parents");
  c.skeleton.parents.assign(parents.data(), parents.data() + parents.size());
  c.skeleton.heads = z.matrix("skeleton_heads");
  c.skeleton.tails = z.matrix("skeleton_tails");
  try {  // sizes, parents before children (so no cycles), finite joints: the message names the file
    c.skeleton.validate();
  } catch (const InputError& e) {
    throw InputError(path.string() + ": 'skeleton_parents'/'skeleton_heads'/'skeleton_tails': " + e.what());
  }
  if (c.skeleton.bone_count() != c.rig.bone_count)
    throw InputError(path.string() + ": the skeleton has " + std::to_string(c.skeleton.bone_count()) +
                     " bones, the rig " + std::to_string(c.rig.bone_count));
  Eigen::VectorXi driven = z.int_vector("skeleton_driven");
  if (driven.size() != c.skeleton.bone_count())
    throw InputError(path.string() + ": 'skeleton_driven' has " + std::to_string(driven.size()) + " entries for " +
                     std::to_string(c.skeleton.bone_count()) + " bones");
  c.driven.assign(driven.data(), driven.data() + driven.size());
  auto lbs = [&](const char* inf, const char* coef) {
    SkinningRig r;
    r.method = SkinningMethod::lbs;
    r.bone_count = c.rig.bone_count;
    r.rest = c.rig.rest;
    r.influences = z.int_matrix(inf);
    r.coefficients = z.matrix(coef);
    r.validate(path.string() + " '" + inf + "'");
    return r;
  };
  c.lbs = lbs("lbs_influences", "lbs_coefficients");
  c.template_lbs = lbs("template_influences", "template_coefficients");
  if (z.has("character")) {
    try {
      c.character = nlohmann::json::parse(z.text("character"));
    } catch (const nlohmann::json::exception&) {
    }
  }
  return c;
}

}  // namespace bodymodel
