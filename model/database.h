// Reading a scan database for `bodymodel build`: which registered mesh belongs to which
// subject and pose (DB/scans.csv), the subjects' labels (DB/subjects.csv) and the pose labels
// (joint rotations, DB/truth/<scan>.pose.csv when present), with the meshes from a folder of
// template-topology meshes named by scan id (REG/<scan_id>.ply or .obj).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "core/progress.h"
#include "model/body_model.h"

namespace bodymodel {

struct DatabaseReadSummary {
  int scans_listed = 0;
  int scans_read = 0;
  std::vector<std::string> missing;    // scan ids without a mesh in REG/
  int scans_with_pose_labels = 0;
};

// Labels: every numeric column of subjects.csv (units from the name: *_cm cm, *_kg kg,
// *_pct %, *_years years, muscle %), plus "sex" (0 female, 1 male) from the sex column; pose
// labels "pose:<bone>:rx|ry|rz" (rotation-vector components, radians) from the pose files
// (standard-pose scans without a file get 0, other scans without one NaN = unknown).
// A label cell is empty (unknown) or a finite number of at most 1e6 in magnitude, not negative
// for a length, mass, volume or age (units cm, kg, L, years); InputError naming the file, line
// and column otherwise (read_registered_folder's table too).
// Throws InputError naming the file and line for malformed tables, a mesh whose topology
// differs from the first one's, or when no listed scan has a mesh.
ModelBuildInput read_registered_database(const std::filesystem::path& registered_dir,
                                         const std::filesystem::path& database_dir,
                                         DatabaseReadSummary* summary = nullptr,
                                         const ProgressCallback& progress = {});

// ---- A folder of registered meshes with a subjects.csv (FAUST, SCAPE, synth-db, population) ----
//
// subjects.csv: a header with at least the columns mesh,subject,pose; one row per mesh used.
// `mesh` is the file stem of REG/<mesh>.ply, .obj or .off (the first that exists); `subject`
// groups the meshes of one person; `pose` names the pose. Other columns are subject labels: a
// `sex` column (female/male, f/m) becomes the label "sex" (0/1), numeric columns become labels
// named after the column (units from the name: *_cm, *_kg, *_pct, *_years, *_l); a subject's
// value must be the same on all its rows (empty = unknown). Rows of the CSV are the only meshes
// read: folds are made by listing subsets.
struct RegisteredFolderOptions {
  // Millimetres per unit of the mesh files (1000 for metres: FAUST, SCAPE). Models are in mm.
  double mm_per_unit = 1.0;
  // The pose name of each subject's standard-pose mesh (the shape model's samples and where
  // labels are measured). A subject without a mesh of that pose uses its first listed mesh.
  std::string standard_pose = "standard";
  // Measure height, volume, weight and girths on each subject's standard-pose mesh
  // (core/measure.h, density below) and add them as labels, unless the CSV gives the column.
  bool measure_labels = true;
  int up_axis = 1;                  // for the measurements: 0 x (SCAPE), 1 y (FAUST, MakeHuman), 2 z
  double density_kg_per_l = 1.01;
  // Vertex i is the same point of the body on every mesh but the triangles may differ (SCAPE
  // re-triangulates each pose): every mesh takes the first mesh's triangles, and only the
  // vertex counts must agree. Off: the triangles must be the same too.
  bool use_first_mesh_faces = false;
};

struct RegisteredFolderSummary {
  int meshes = 0, subjects = 0;
  int subjects_without_standard_pose = 0;  // used their first listed mesh
  std::vector<std::string> measured_labels;
  int measurement_failures = 0;            // subjects whose mesh could not be measured (NaN labels)
  std::string first_measurement_failure;
  std::vector<std::string> dropped_labels;  // known for < 2 subjects or equal for all
  int meshes_with_other_faces = 0;          // use_first_mesh_faces: meshes whose triangles differed
};

// Reads the meshes subjects.csv lists from `registered_dir`. Throws InputError (naming the file
// and line, or the mesh) for a missing column, a mesh the CSV names that the folder does not
// have (all such meshes counted, the first ones named), a mesh listed twice, a subject whose
// label differs between rows, or a mesh whose topology differs from the first one's. Vertex
// coordinates are returned in mm (× mm_per_unit). Pose labels: none (in.pose_labels empty).
ModelBuildInput read_registered_folder(const std::filesystem::path& registered_dir,
                                       const std::filesystem::path& subjects_csv,
                                       const RegisteredFolderOptions& options = {},
                                       RegisteredFolderSummary* summary = nullptr,
                                       const ProgressCallback& progress = {});

// The rows of a subjects.csv (mesh, subject, pose) without reading meshes; InputError naming the
// file and line for a missing column or an empty mesh name.
struct MeshTableRow {
  std::string mesh, subject, pose;
};
std::vector<MeshTableRow> read_mesh_table(const std::filesystem::path& subjects_csv);

// REG/<stem>.ply, .obj or .off, whichever exists first; empty path when none does.
std::filesystem::path find_registered_mesh(const std::filesystem::path& dir, const std::string& stem);

// Subject labels of a database, by subject id (for evaluations): names, units, values.
struct SubjectTable {
  std::vector<std::string> ids;
  std::vector<LabelInfo> labels;
  Eigen::MatrixXd values;  // #subjects by #labels
};
SubjectTable read_subject_table(const std::filesystem::path& subjects_csv);

struct ScanTableRow {
  std::string scan_id, subject_id, pose;
};
std::vector<ScanTableRow> read_scan_table(const std::filesystem::path& scans_csv);

}  // namespace bodymodel
