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
// Throws InputError naming the file and line for malformed tables, a mesh whose topology
// differs from the first one's, or when no listed scan has a mesh.
ModelBuildInput read_registered_database(const std::filesystem::path& registered_dir,
                                         const std::filesystem::path& database_dir,
                                         DatabaseReadSummary* summary = nullptr,
                                         const ProgressCallback& progress = {});

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
