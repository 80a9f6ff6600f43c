// Everything `bodymodel character` writes for one body, reusable by `crowd` and `demo`:
//   body.obj        the body (standard pose, mm)
//   rig.npz         the MWE rig with skeleton (tools/pipeline/character_file.h)
//   fit.csv         vertex errors (mm) of template SSD, fitted SSD, AS and MWE against the
//                   model's pose morphs, training and held-out poses
//   poses.csv       the range of motion: name, split, how it was made, flipped triangles before
//                   and after the fold repair, each rig's mean and max error (mm) on the pose
//   skinning_error.png  held-out pose with the largest SSD error: pose morph | SSD | AS | MWE,
//                   per-vertex error on a fixed colour scale (skinning_error_scale_mm)
//   character.glb   the SSD rig as glTF 2.0 (when the glTF writer is available)
//   judge.csv       with judge poses only: each rig's vertex error (mm) on real poses that are not
//                   the model's own, after the same pose fit for every rig
//                   (tools/pipeline/character_judge.h), per pose and over all of them
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/progress.h"
#include "model/body_model.h"
#include "tools/pipeline/character.h"
#include "tools/pipeline/character_judge.h"

namespace bodymodel {

struct CharacterJobOptions {
  CharacterOptions character;
  double error_scale_mm = 60;   // colour scale of skinning_error.png (0 blue → red)
  bool write_pictures = true;
  bool write_glb = true;
  // Real poses of the body (e.g. registrations of the person the body was unposed from) to judge
  // every rig on besides the model's pose morphs; none = no judge.csv.
  std::vector<JudgePose> judge_poses;
  RigPoseFitOptions judge_fit;
};

struct CharacterJobResult {
  std::vector<RigErrorRow> errors;
  nlohmann::json character;     // what went into rig.npz's 'character' key
  int training_poses = 0, held_out_poses = 0;
  double examples_seconds = 0, fit_seconds = 0;
  // Flipped triangles summed over the range of motion before and after the fold repair.
  int flipped_before_repair = 0, flipped_after_repair = 0;
  bool wrote_glb = false;
  std::string glb_note;         // why not, when not
  std::vector<JudgeRow> judged; // judge_rigs_on_poses rows when judge poses were given
  double judge_seconds = 0;
};

// Writes the files above into `dir` (which must exist). `description` is stored in the rig's
// 'character' JSON (how the body was made).
CharacterJobResult write_character(const BodyModel& model, const Eigen::MatrixX3d& V, const std::filesystem::path& dir,
                                   const nlohmann::json& description, const CharacterJobOptions& options = {},
                                   const ProgressCallback& progress = {});

// The row of `rows` for a method and split (InputError if absent).
const RigErrorRow& find_row(const std::vector<RigErrorRow>& rows, const std::string& method, const std::string& split);

}  // namespace bodymodel
