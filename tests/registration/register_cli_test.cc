// The register verb on bad databases: a clear one-line error and a non-zero exit, never a crash.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sys/wait.h>

#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "registration/fixtures.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

struct CliRun {
  int code;
  std::string err;
};

CliRun run(const std::string& args) {
  const fs::path err = fs::temp_directory_path() / "bodymodel_reg_cli_err.txt";
  const std::string cmd = std::string(BODYMODEL_EXE) + " " + args + " 2> " + err.string() +
                          " > /dev/null";
  const int status = std::system(cmd.c_str());
  CliRun r{WIFEXITED(status) ? WEXITSTATUS(status) : -1, read_text_file(err)};
  fs::remove(err);
  return r;
}

TEST(RegisterCli, BadDatabasesGiveClearErrors) {
  const fs::path db = fs::temp_directory_path() / "bodymodel_reg_cli_db";
  fs::remove_all(db);
  CliRun r = run("register " + db.string() + " --out " + (db / "reg").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("does not exist"), std::string::npos) << r.err;

  fs::create_directories(db / "scans");
  write_text_file(db / "scans.csv", "scan_id,subject_id,pose\nnan_scan,s0,standard\n");
  PointCloud scan = test::scan_of(test::potato(800.0, 3), 3000, 1);
  {  // ASCII PLY by hand: the library's writer refuses NaN, a scanner's file may not.
    std::ofstream f(db / "scans" / "nan_scan.ply");
    f << "ply\nformat ascii 1.0\nelement vertex " << scan.P.rows()
      << "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\n"
         "property float ny\nproperty float nz\nend_header\n";
    for (Eigen::Index i = 0; i < scan.P.rows(); ++i) {
      f << (i == 5 ? std::string("nan") : std::to_string(scan.P(i, 0))) << " " << scan.P(i, 1)
        << " " << scan.P(i, 2) << " " << scan.N(i, 0) << " " << scan.N(i, 1) << " "
        << scan.N(i, 2) << "\n";
    }
  }
  write_text_file(db / "scans" / "nan_scan.landmarks.json", "{}");
  r = run("register " + db.string() + " --out " + (db / "reg").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("NaN"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(db / "reg" / "nan_scan.ply"));

  write_point_cloud(db / "scans" / "nan_scan.ply", test::scan_of(test::potato(800.0, 3), 3000, 1));
  write_text_file(db / "scans" / "nan_scan.landmarks.json", R"({"elbow_tip": [0, 0, 0]})");
  r = run("register " + db.string() + " --out " + (db / "reg").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("unknown landmark name 'elbow_tip'"), std::string::npos) << r.err;
  fs::remove_all(db);
}

}  // namespace
}  // namespace bodymodel
