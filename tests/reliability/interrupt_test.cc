// Interrupted runs: SIGINT/SIGTERM during writing leave no partial file under a final name and
// no temporaries (core/io/interrupt_cleanup.h), and a rerun completes, skipping finished items.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "core/io/atomic_write.h"
#include "core/io/interrupt_cleanup.h"
#include "core/io/mesh_io.h"
#include "reliability/cli_helpers.h"
#include "support/fixtures.h"

namespace bodymodel {
namespace {

using namespace reliability;

TEST(InterruptCleanup, RecognisesOnlyItsOwnTemporaries) {
  EXPECT_TRUE(is_atomic_write_temporary(".body_001.ply.tmp4242_0", 4242));
  EXPECT_TRUE(is_atomic_write_temporary(".a.tmp.ply.tmp7_123", 7));
  EXPECT_FALSE(is_atomic_write_temporary(".body_001.ply.tmp4242_0", 424));
  EXPECT_FALSE(is_atomic_write_temporary(".body_001.ply.tmp42421_0", 4242));
  EXPECT_FALSE(is_atomic_write_temporary("body_001.ply.tmp4242_0", 4242));
  EXPECT_FALSE(is_atomic_write_temporary(".tmp4242_0", 4242));
  EXPECT_FALSE(is_atomic_write_temporary(".a.ply.tmp4242_", 4242));
  EXPECT_FALSE(is_atomic_write_temporary(".a.ply.tmp4242_1x", 4242));
  EXPECT_FALSE(is_atomic_write_temporary(".a.ply", 4242));
}

// A child process is signalled while write_atomically has written 1 MB of a file: with the
// handlers installed nothing is left; without them the temporary stays (never the final name).
int interrupted_write(const fs::path& dir, int sig, bool handlers) {
  const pid_t pid = fork();
  if (pid == 0) {
    if (handlers) install_interrupt_cleanup();
    write_atomically(dir / "out.bin", [sig](std::ostream& o) {
      o << std::string(1 << 20, 'x');
      o.flush();
      ::raise(sig);
      o << "never reached";
    });
    _exit(0);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFSIGNALED(status) ? WTERMSIG(status) : -1;
}

TEST(InterruptCleanup, SignalDuringWriteLeavesNothing) {
  for (int sig : {SIGINT, SIGTERM}) {
    fixtures::TempDir dir;
    EXPECT_EQ(interrupted_write(dir.path, sig, true), sig);
    EXPECT_FALSE(fs::exists(dir / "out.bin"));
    EXPECT_TRUE(files_under(dir.path).empty()) << files_under(dir.path).front();
  }
  fixtures::TempDir dir;  // control: the default action alone leaves the hidden temporary
  EXPECT_EQ(interrupted_write(dir.path, SIGTERM, false), SIGTERM);
  EXPECT_FALSE(fs::exists(dir / "out.bin"));
  EXPECT_EQ(temporaries_under(dir.path).size(), 1u);
}

// Every file under `dir` is complete: meshes and point clouds parse with all their elements,
// JSON parses, text ends with a newline.
void expect_complete(const fs::path& dir) {
  for (const auto& p : files_under(dir)) {
    const std::string ext = p.extension().string(), name = p.filename().string();
    SCOPED_TRACE(p.string());
    if (ext == ".ply" && p.parent_path().filename() == "scans") {
      EXPECT_GT(read_point_cloud(p).P.rows(), 1000);
    } else if (ext == ".ply") {
      EXPECT_EQ(read_mesh(p).V.rows(), 13380);
    } else if (ext == ".json") {
      EXPECT_NO_THROW(nlohmann::json::parse(read_text_file(p)));
    } else if (ext == ".csv") {
      const std::string t = read_text_file(p);
      EXPECT_TRUE(!t.empty() && t.back() == '\n');
    }
  }
}

TEST(InterruptCleanup, KilledBatchVerbsLeaveCompleteFilesAndRerunsFinish) {
  fixtures::TempDir dir;
  const fs::path db = dir / "db", reg = dir / "reg", log = dir / "log.txt";
  const std::vector<std::string> synth = {"synth-db", "--subjects", "2", "--poses-per-subject", "1",
                                          "--seed", "11", "--jobs", "1", "--out", db.string()};
  // synth-db, Ctrl-C as soon as the first scan file is complete (its next files are being written).
  Child c = spawn_bodymodel(synth, log);
  ASSERT_TRUE(wait_until([&] { return fs::exists(db / "scans" / "s000_p0.ply"); }, 300))
      << read_text_file(log);
  ::kill(c.pid, SIGINT);
  EXPECT_TRUE(c.ended_by(SIGINT)) << read_text_file(log);
  EXPECT_TRUE(temporaries_under(db).empty()) << temporaries_under(db).front();
  EXPECT_FALSE(fs::exists(db / "scans.csv"));  // the tables are written last
  expect_complete(db);

  std::string out;
  std::vector<std::string> again = synth;
  again.push_back("--force");
  ASSERT_EQ(run_bodymodel(again, log, &out), 0) << out;
  EXPECT_TRUE(fs::exists(db / "scans.csv"));
  expect_complete(db);

  // register (pose fit only, one scan at a time), SIGTERM after the first registered scan.
  const std::vector<std::string> reg_args = {"register", db.string(), "--out", reg.string(),
                                             "--pose-only", "--jobs", "1"};
  c = spawn_bodymodel(reg_args, log);
  ASSERT_TRUE(wait_until([&] { return fs::exists(reg / "s000_p0.summary.csv"); }, 300))
      << read_text_file(log);
  ::kill(c.pid, SIGTERM);
  EXPECT_TRUE(c.ended_by(SIGTERM)) << read_text_file(log);
  EXPECT_TRUE(temporaries_under(reg).empty()) << temporaries_under(reg).front();
  expect_complete(reg);
  const auto first_time = fs::last_write_time(reg / "s000_p0.ply");

  ASSERT_EQ(run_bodymodel(reg_args, log, &out), 0) << out;
  EXPECT_NE(out.find("already registered"), std::string::npos) << out;
  EXPECT_EQ(fs::last_write_time(reg / "s000_p0.ply"), first_time);  // skipped, not redone
  for (const char* id : {"s000_p0", "s000_p1", "s001_p0", "s001_p1"})
    EXPECT_TRUE(fs::exists(reg / (std::string(id) + ".summary.csv"))) << id;
  EXPECT_TRUE(temporaries_under(reg).empty());
  expect_complete(reg);
}

}  // namespace
}  // namespace bodymodel
