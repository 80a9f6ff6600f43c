// Replays inputs through the fuzz targets' readers (tests/fuzz/readers.h): the inputs the fuzzer
// once crashed on (kept in tests/reliability/inputs/<target>/, each fixed) and a set of hostile
// inputs written here. Each must be read or rejected with an InputError naming what is wrong;
// under the sanitizer build (scripts/test.sh --sanitize) any memory or UB error fails the run.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "core/io/atomic_write.h"
#include "fuzz/readers.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

const fs::path kTests = fs::path(__FILE__).parent_path().parent_path();

// Runs a reader; returns "" when it read the input, else the rejection message. Any other
// exception type fails the test.
std::string outcome(const std::string& target, const std::string& bytes) {
  try {
    fuzz::readers().at(target)(bytes);
    return "";
  } catch (const InputError& e) {
    return e.what();
  } catch (const NumericalError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << target << ": " << typeid(e).name() << " escaped the reader: " << e.what();
    return "?";
  }
}

TEST(ReaderRegressions, EveryFuzzTargetHasAReplayableReader) {
  std::set<std::string> targets;
  for (const auto& e : fs::directory_iterator(kTests / "fuzz")) {
    const std::string n = e.path().filename().string();
    if (n.rfind("fuzz_", 0) == 0 && e.path().extension() == ".cc" && n != "fuzz_common.h")
      targets.insert(e.path().stem().string().substr(5));
  }
  EXPECT_GE(targets.size(), 14u);
  for (const auto& t : targets) EXPECT_TRUE(fuzz::readers().count(t)) << "fuzz_" << t << " has no reader";
  for (const auto& [t, f] : fuzz::readers()) EXPECT_TRUE(targets.count(t)) << t << " has no fuzz target";
}

TEST(ReaderRegressions, KeptFuzzFindingsAreRejectedCleanly) {
  // The message the README's bad-input table shows for a finding (others: read or refused).
  const std::map<std::string, std::string> expected = {
      {"ply/nan-list-count-in-vertex.ply", "implausible list length"},
      {"npz/inflate-bomb-header.npz", "more than deflate can produce"},
      {"mhskel/number-overflow-6E565.json", "number overflow"},
      {"mhw/number-overflow.mhw", "number overflow"},
      {"dmat/huge-ascii-header.dmat", "more values than the file holds"},
  };
  int replayed = 0, checked = 0;
  const fs::path dir = kTests / "reliability" / "inputs";
  for (const auto& t : fs::directory_iterator(dir)) {
    if (!t.is_directory()) continue;
    const std::string target = t.path().filename().string();
    ASSERT_TRUE(fuzz::readers().count(target)) << "inputs/" << target << ": no such reader";
    for (const auto& f : fs::directory_iterator(t.path())) {
      // Hangs are findings too (the fuzzer stops at 10 s): each input is read or refused at once.
      const auto start = std::chrono::steady_clock::now();
      const std::string message = outcome(target, read_text_file(f.path()));
      const auto it = expected.find(target + "/" + f.path().filename().string());
      if (it != expected.end()) {
        EXPECT_NE(message.find(it->second), std::string::npos) << f.path() << ": " << message;
        ++checked;
      }
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      EXPECT_LT(seconds, 2.0) << f.path();
      ++replayed;
    }
  }
  EXPECT_EQ(checked, static_cast<int>(expected.size()));
  RecordProperty("replayed", replayed);
}

struct Hostile {
  std::string target, bytes, expect;  // expect: a substring of the message ("" = reads fine)
};

TEST(ReaderRegressions, HostileInputsGiveSpecificMessages) {
  const std::string nan_bin = [] {
    std::string s = "0 0\n1 1\n";
    const double v = std::numeric_limits<double>::quiet_NaN();
    s.append(reinterpret_cast<const char*>(&v), sizeof v);
    return s;
  }();
  const std::vector<Hostile> cases = {
      {"obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "4"},
      {"obj", "v 0 nan 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "NaN"},
      {"ply", "ply\nformat ascii 1.0\nelement vertex 1000000000\nproperty float x\nend_header\n", ""},
      {"off", "OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "ends after 0 faces"},
      {"off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n", "a face needs at least 3"},
      {"off", "OFF\n3 1 0\n0 0 0\n1 0 inf\n0 1 0\n3 0 1 2\n", "NaN or infinite"},
      {"off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n", "after the last face"},
      {"npz", std::string("PK\x03\x04", 4) + std::string(20, '\xff'), ""},
      {"bvh", "HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 7 Xposition\n}\n", ""},
      {"mh_target", "0 1 2\n", "expected 3 offsets"},
      {"mh_target", "100 0 0 0\n", "exceeds the base mesh"},
      {"mh_target", "5 0 nan 0\n", "expected 3 offsets"},
      {"mhskel", R"({"bones": {"a": {"head": "j", "tail": "j"}}, "joints": {"j": [1e9]}})",
       "non-integer vertex"},
      {"mhskel", R"({"bones": {"a": {"head": "j", "tail": "j", "parent": "a"}}, "joints": {"j": [0]}})",
       "expected one root bone"},
      {"mhw", R"({"weights": {"root": [[0, 1], [99999999, 1]]}})", "outside the base mesh"},
      {"mhw", R"({"weights": {"arm": [[0, 1]]}})", "is not in the default skeleton"},
      {"landmarks", R"({"chin": [0, 1]})", "must be an array of three numbers"},
      {"landmarks", R"({"nose": [0, 1, 2]})", "unknown landmark name 'nose'"},
      {"landmarks", "[1, 2", "parse error"},
      {"labels_csv", "scan_id,subject_id\na,b\n", "no 'pose' column"},
      {"labels_csv", "scan_id,subject_id,pose\na,b\n", "2 fields, the header has 3"},
      {"pose_csv", "bone,rx,ry,rz\nelbow,0,0,0\n", "elbow"},
      {"pose_csv", "bone,rx,ry,rz\nspine,0,nan,0\n", ""},
      {"tgf", "1 0 0 0\n#\n1 5\n", "out of range"},
      {"tgf", "1 0 inf 0\n#\n", "not finite"},
      {"dmat", "2 3\n1 2 3\n", ""},
      {"dmat", nan_bin, ""},
      {"mhclo", "verts 0\n1 2 300 0.2 0.3 0.5\n", "line 2: vertex index 300 is outside [0, 100)"},
      {"mhclo", "x_scale 1 2 0\nverts 0\n1\n", "line 1: scale denominator must be positive"},
      {"mhclo", "verts 0\n1\ndelete_verts\n9 - 2\n", "line 4: delete_verts range 9 - 2 is reversed"},
      {"mhmat", "name x\nshininess 2\n", "line 2: 'shininess' must be in [0, 1]"},
      {"model_npz", "", ""},
      {"rig_npz", "PK", ""},
  };
  for (const auto& c : cases) {
    const std::string got = outcome(c.target, c.bytes);
    EXPECT_FALSE(got.empty()) << c.target << " accepted '" << c.bytes << "'";
    EXPECT_NE(got.find(c.expect), std::string::npos)
        << c.target << " on '" << c.bytes << "': message '" << got << "' lacks '" << c.expect << "'";
  }
}

}  // namespace
}  // namespace bodymodel
