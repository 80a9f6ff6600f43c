// Interrupted runs: SIGINT/SIGTERM during writing leave no partial file under a final name and
// no temporaries (core/io/interrupt_cleanup.h), and a rerun completes, skipping finished items.
#include <gtest/gtest.h>

#include <fstream>
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
      EXPECT_NO_THROW((void)nlohmann::json::parse(read_text_file(p)));
    } else if (ext == ".csv") {
      const std::string t = read_text_file(p);
      EXPECT_TRUE(!t.empty() && t.back() == '\n');
    }
  }
}

// The small database of these tests, made once by an uninterrupted run: what every resumed run
// must end identical to, byte for byte.
const std::vector<std::string>& synth_args() {
  static const std::vector<std::string> args = {"synth-db", "--subjects", "2", "--poses-per-subject",
                                                "1", "--seed", "11", "--jobs", "1"};
  return args;
}
std::vector<std::string> synth_into(const fs::path& out) {
  std::vector<std::string> a = synth_args();
  a.push_back("--out");
  a.push_back(out.string());
  return a;
}
const fs::path& clean_database() {
  static fixtures::TempDir dir;
  static const fs::path db = [] {
    std::string out;
    EXPECT_EQ(run_bodymodel(synth_into(dir / "db"), dir / "log.txt", &out), 0) << out;
    return dir / "db";
  }();
  return db;
}

// "skipped N existing" from synth-db's output, -1 when absent.
int skipped_count(const std::string& out) {
  const size_t at = out.find("skipped ");
  if (at == std::string::npos) return -1;
  return std::atoi(out.c_str() + at + 8);
}

// A resumed synth-db keeps every complete scan, makes again every scan with a file missing or
// unreadable (all four files), rebuilds the tables, removes temporaries of killed runs, and
// ends byte-identical to a clean run.
TEST(ResumableSynthDb, DamagedDatabaseIsCompletedIdenticalToACleanRun) {
  const fs::path& clean = clean_database();
  fixtures::TempDir dir;
  const fs::path db = dir / "db", log = dir / "log.txt";
  fs::copy(clean, db, fs::copy_options::recursive);
  ASSERT_EQ(folder_difference(clean, db), "");
  const auto kept_time = fs::last_write_time(db / "scans" / "s000_p0.ply");
  fs::remove(db / "truth" / "s001_p0.ply");            // a scan with one file missing
  {                                                    // a scan with a truncated file
    const std::string bytes = read_text_file(db / "scans" / "s000_p1.ply");
    std::ofstream(db / "scans" / "s000_p1.ply", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  fs::remove(db / "scans" / "s001_p1.landmarks.json");  // another scan, another file
  fs::remove(db / "scans.csv");                         // a table
  std::ofstream(db / "truth" / ".s001_p1.ply.tmp999999_0") << "half a file";  // SIGKILL leftover
  ASSERT_NE(folder_difference(clean, db), "");

  std::string out;
  ASSERT_EQ(run_bodymodel(synth_into(db), log, &out), 0) << out;  // no --force needed
  EXPECT_EQ(skipped_count(out), 1) << out;  // only s000_p0 was complete
  EXPECT_NE(out.find("resuming"), std::string::npos) << out;
  EXPECT_EQ(folder_difference(clean, db), "") << out;
  EXPECT_EQ(fs::last_write_time(db / "scans" / "s000_p0.ply"), kept_time);  // kept, not redone
  EXPECT_TRUE(temporaries_under(db).empty());

  // A finished database: everything is kept, nothing changes.
  ASSERT_EQ(run_bodymodel(synth_into(db), log, &out), 0) << out;
  EXPECT_EQ(skipped_count(out), 4) << out;
  EXPECT_EQ(folder_difference(clean, db), "") << out;

  // Other settings into the same folder: refused without --force (naming the difference), and
  // nothing is touched; with --force every scan is made again, none kept.
  std::vector<std::string> other = synth_into(db);
  other[6] = "12";  // --seed
  EXPECT_EQ(run_bodymodel(other, log, &out), 2) << out;
  ASSERT_EQ(error_lines(out).size(), 1u) << out;
  EXPECT_NE(error_lines(out)[0].find("seed was 11, now 12"), std::string::npos) << out;
  EXPECT_EQ(folder_difference(clean, db), "");
  other.push_back("--force");
  ASSERT_EQ(run_bodymodel(other, log, &out), 0) << out;
  EXPECT_EQ(skipped_count(out), 0) << out;
  EXPECT_NE(read_text_file(db / "scans" / "s000_p0.landmarks.json"),
            read_text_file(clean / "scans" / "s000_p0.landmarks.json"));
}

TEST(InterruptCleanup, KilledBatchVerbsLeaveCompleteFilesAndRerunsFinish) {
  fixtures::TempDir dir;
  const fs::path db = dir / "db", reg = dir / "reg", log = dir / "log.txt";
  const std::vector<std::string> synth = synth_into(db);
  // synth-db, Ctrl-C as soon as the first scan is complete (the next one is being written).
  Child c = spawn_bodymodel(synth, log);
  ASSERT_TRUE(wait_until([&] { return fs::exists(db / "truth" / "s000_p0.pose.csv"); }, 300))
      << read_text_file(log);
  ::kill(c.pid, SIGINT);
  EXPECT_TRUE(c.ended_by(SIGINT)) << read_text_file(log);
  EXPECT_TRUE(temporaries_under(db).empty()) << temporaries_under(db).front();
  EXPECT_FALSE(fs::exists(db / "scans.csv"));  // the tables are written last
  expect_complete(db);

  // The rerun keeps the finished scan(s) and ends identical to the uninterrupted run.
  std::string out;
  std::vector<std::string> again = synth;
  again.push_back("--force");
  ASSERT_EQ(run_bodymodel(again, log, &out), 0) << out;
  EXPECT_GE(skipped_count(out), 1) << out;
  EXPECT_LE(skipped_count(out), 3) << out;
  EXPECT_TRUE(fs::exists(db / "scans.csv"));
  expect_complete(db);
  EXPECT_EQ(folder_difference(clean_database(), db), "");

  // register (pose fit only, one scan at a time), SIGTERM after the first registered scan.
  // Without the hand stage: what is tested is the interrupt, and the hand stage's two starts per
  // hand took this test past its 600 s timeout in the sanitizer build.
  const std::vector<std::string> reg_args = {"register", db.string(), "--out", reg.string(),
                                             "--pose-only", "--hand-stage", "off", "--jobs", "1"};
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
