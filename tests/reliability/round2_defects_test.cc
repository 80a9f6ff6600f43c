// Issue 27 ("Reliability, round 2") in the library: each defect found by trying hostile and
// careless inputs, reproduced on tiny inputs made in code. Command-line cases are in
// hostile_campaign_test.cc.
#include <gtest/gtest.h>

#include <unistd.h>

#include <zlib.h>

#include <cmath>
#include <fstream>
#include <limits>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/bvh.h"
#include "core/io/mesh_io.h"
#include "core/io/npz.h"
#include "core/measure.h"
#include "core/retarget.h"
#include "fuzz/tiny_files.h"
#include "reliability/cli_helpers.h"
#include "support/fixtures.h"
#include "tools/pipeline/character_file.h"
#include "tools/pipeline/folder_settings.h"
#include "tools/pipeline/output_folder.h"

namespace bodymodel {
namespace {

using namespace reliability;

// ---- 5. crash: deep BVH nesting ----------------------------------------------------------------

std::string nested_bvh(int depth) {
  std::string s = "HIERARCHY\nROOT j0\n{\nOFFSET 0 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n";
  for (int d = 1; d < depth; ++d) s += "JOINT j" + std::to_string(d) + "\n{\nOFFSET 0 1 0\n";
  for (int d = 1; d < depth; ++d) s += "}\n";
  return s + "}\nMOTION\nFrames: 1\nFrame Time: 0.033\n0 0 0\n";
}

TEST(ReaderHardening, BvhNestingIsBounded) {
  // 20 000 levels overflowed the stack in parse_joint (SIGSEGV).
  const std::string m = message_of([] { parse_bvh(nested_bvh(20000), "deep.bvh"); });
  EXPECT_NE(m.find("BVH 'deep.bvh' line"), std::string::npos) << m;
  EXPECT_NE(m.find("nested more than 256 levels"), std::string::npos) << m;
  EXPECT_NO_THROW(parse_bvh(nested_bvh(100), "ok.bvh"));
}

// ---- 7. a PLY whose header counts disagree with its data ----------------------------------------

TEST(ReaderHardening, PlyHeaderCountsThatDisagreeAreNamed) {
  fixtures::TempDir dir;
  const Mesh m = fixtures::box(10, 20, 30);
  write_mesh(dir / "ok.ply", m.V, m.F);
  const std::string good = read_text_file(dir / "ok.ply");
  ASSERT_NO_THROW(read_mesh(dir / "ok.ply"));
  auto with_header = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    const size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos);
    s.replace(at, from.size(), to);
    return s;
  };
  const int nv = static_cast<int>(m.V.rows()), nf = static_cast<int>(m.F.rows());
  const std::vector<std::pair<std::string, std::string>> cases = {
      // One vertex fewer than the data: the faces are read from vertex bytes (the message used to
      // be "face 0 refers to vertex -1023213568").
      {"element vertex " + std::to_string(nv), "element vertex " + std::to_string(nv - 1)},
      {"element vertex " + std::to_string(nv), "element vertex " + std::to_string(nv + 1)},
      // Fewer faces than the data: the last faces were dropped without a word.
      {"element face " + std::to_string(nf), "element face " + std::to_string(nf - 2)},
      {"element face " + std::to_string(nf), "element face " + std::to_string(nf + 1)},
  };
  for (const auto& [from, to] : cases) {
    SCOPED_TRACE(to);
    write_text_file(dir / "bad.ply", with_header(from, to));
    const std::string msg = message_of([&] { read_mesh(dir / "bad.ply"); });
    EXPECT_NE(msg.find("bad.ply"), std::string::npos) << msg;
    EXPECT_NE(msg.find("the header announces vertex"), std::string::npos) << msg;
  }
  // ASCII too.
  write_mesh(dir / "ascii.ply", m.V, m.F, Eigen::MatrixX3d(), true);
  std::string ascii = read_text_file(dir / "ascii.ply");
  ascii.replace(ascii.find("element face " + std::to_string(nf)), 13 + std::to_string(nf).size(),
                "element face " + std::to_string(nf - 1));
  write_text_file(dir / "ascii_bad.ply", ascii);
  const std::string msg = message_of([&] { read_mesh(dir / "ascii_bad.ply"); });
  EXPECT_NE(msg.find("the header's counts disagree with the data"), std::string::npos) << msg;
}

// ---- 7. messages of writes that cannot happen ----------------------------------------------------

TEST(ReaderHardening, WritesThatCannotHappenSayWhy) {
  fixtures::TempDir dir;
  fs::create_directories(dir / "o");
  // `encode --out o/` said "Not a directory".
  for (const fs::path& p : {dir / "o" / "", dir / "o"}) {
    const std::string msg = message_of([&] { write_text_file(p, "x"); });
    EXPECT_NE(msg.find("it is a folder; expected a file name"), std::string::npos) << p << ": " << msg;
  }
  EXPECT_TRUE(temporaries_under(dir.path).empty());
  // A folder that cannot be made said "No such file or directory" (the error of the check after
  // the attempt); /sys refuses new folders even to root.
  if (fs::is_directory("/sys/kernel")) {
    const std::string msg = message_of([&] { ensure_directory("/sys/bodymodel_test_no/out"); });
    EXPECT_NE(msg.find("cannot create folder '/sys/bodymodel_test_no/out'"), std::string::npos) << msg;
    EXPECT_EQ(msg.find("No such file or directory"), std::string::npos) << msg;
  }
  write_text_file(dir / "file", "x");
  const std::string msg = message_of([&] { ensure_directory(dir / "file"); });
  EXPECT_NE(msg.find("a file of that name is in the way"), std::string::npos) << msg;
}

// ---- 8. .npz dtypes as documented, old files still read -----------------------------------------

// A .npz as written before integers were int32: one stored member, '<i8', shape (2, 3).
std::string legacy_npz_int64(const std::string& key, const std::vector<int64_t>& values) {
  auto u16 = [](std::string& s, uint16_t v) { s.append(reinterpret_cast<const char*>(&v), 2); };
  auto u32 = [](std::string& s, uint32_t v) { s.append(reinterpret_cast<const char*>(&v), 4); };
  std::string header = "{'descr': '<i8', 'fortran_order': False, 'shape': (2, 3), }";
  header.append(64 - (10 + header.size() + 1) % 64, ' ');
  header.push_back('\n');
  std::string npy = "\x93NUMPY";
  npy += '\x01';
  npy += '\x00';
  u16(npy, static_cast<uint16_t>(header.size()));
  npy += header;
  npy.append(reinterpret_cast<const char*>(values.data()), values.size() * 8);
  const uint32_t crc = static_cast<uint32_t>(crc32(0L, reinterpret_cast<const Bytef*>(npy.data()), npy.size()));
  const std::string name = key + ".npy";
  std::string zip, central;
  u32(zip, 0x04034b50), u16(zip, 20), u16(zip, 0), u16(zip, 0), u16(zip, 0), u16(zip, 0x21), u32(zip, crc);
  u32(zip, static_cast<uint32_t>(npy.size())), u32(zip, static_cast<uint32_t>(npy.size()));
  u16(zip, static_cast<uint16_t>(name.size())), u16(zip, 0);
  zip += name + npy;
  u32(central, 0x02014b50), u16(central, 20), u16(central, 20), u16(central, 0), u16(central, 0), u16(central, 0);
  u16(central, 0x21), u32(central, crc), u32(central, static_cast<uint32_t>(npy.size()));
  u32(central, static_cast<uint32_t>(npy.size())), u16(central, static_cast<uint16_t>(name.size()));
  for (int i = 0; i < 4; ++i) u16(central, 0);
  u32(central, 0), u32(central, 0);
  central += name;
  const uint32_t cd = static_cast<uint32_t>(zip.size());
  zip += central;
  u32(zip, 0x06054b50), u16(zip, 0), u16(zip, 0), u16(zip, 1), u16(zip, 1);
  u32(zip, static_cast<uint32_t>(central.size())), u32(zip, cd), u16(zip, 0);
  return zip;
}

TEST(ReaderHardening, NpzIntegersAreInt32AndInt64FilesStillRead) {
  Npz z;
  Eigen::MatrixXi F(2, 3);
  F << 0, 1, 2, 2, 1, 3;
  z.put("faces", F);
  z.put("parents", Eigen::VectorXi(Eigen::Vector3i(-1, 0, 1)));
  z.put_int("bone_count", 3);
  z.put("rest", Eigen::MatrixXd(Eigen::MatrixXd::Ones(2, 3)));
  const Npz back = Npz::parse(z.serialize(), "mem");
  EXPECT_EQ(back.arrays().at("faces").dtype, "<i4");
  EXPECT_EQ(back.arrays().at("parents").dtype, "<i4");
  EXPECT_EQ(back.arrays().at("bone_count").dtype, "<i4");
  EXPECT_EQ(back.arrays().at("rest").dtype, "<f8");
  EXPECT_EQ(back.int_matrix("faces"), F);
  EXPECT_EQ(back.scalar("bone_count"), 3);
  // A file written before (int64 integers, float64 counts) reads the same.
  const Npz legacy = Npz::parse(legacy_npz_int64("faces", {0, 1, 2, 2, 1, 3}), "legacy.npz");
  EXPECT_EQ(legacy.arrays().at("faces").dtype, "<i8");
  EXPECT_EQ(legacy.int_matrix("faces"), F);
  // The rig and model writers: every integer array int32.
  fixtures::TempDir dir;
  tiny::write_rig(dir / "rig.npz", true);
  const Npz r = Npz::load(dir / "rig.npz");
  for (const char* key : {"bone_count", "faces", "influences", "skeleton_parents"})
    EXPECT_EQ(r.arrays().at(key).dtype, "<i4") << key;
  const Npz m = Npz::parse(tiny::model_npz().serialize(), "model");
  for (const auto& [key, a] : m.arrays()) {
    if (!a.is_float && a.text.empty()) {
      EXPECT_EQ(a.dtype, "<i4") << key;
    }
  }
  EXPECT_EQ(m.arrays().at("template_faces").dtype, "<i4");
}

TEST(ReaderHardening, NpzMembersAreDeflated) {
  // Every member was stored uncompressed (the demo model: 106 MB).
  Npz z;
  Eigen::MatrixXi F(3000, 3);
  for (int r = 0; r < F.rows(); ++r) F.row(r) << r, r + 1, r + 2;
  Eigen::MatrixXd V(1000, 3);
  for (int r = 0; r < V.rows(); ++r) V.row(r) << std::round(std::sin(r) * 1000), 0.5 * (r % 7), 100.0;
  z.put("faces", F);
  z.put("vertices", V);
  z.put_text("names", "a\nb\n");
  const std::string bytes = z.serialize();
  // Every local header (the first at 0) says method 8 (deflate) for these compressible members.
  int deflated = 0;
  for (size_t at = 0; (at = bytes.find("PK\x03\x04", at)) != std::string::npos; at += 4)
    deflated += bytes[at + 8] == 8 && bytes[at + 9] == 0;
  EXPECT_EQ(deflated, 3);
  EXPECT_LT(bytes.size(), (F.size() * 4 + V.size() * 8) / 2);
  const Npz back = Npz::parse(bytes, "mem");
  EXPECT_EQ(back.int_matrix("faces"), F);
  EXPECT_EQ(back.matrix("vertices"), V);
  EXPECT_EQ(back.text("names"), "a\nb\n");
}

TEST(ReaderHardening, ModelMetadataHoldsNoAbsolutePaths) {
  fixtures::TempDir dir;
  BodyModel model = load_model([&] {
    tiny::model_npz().save(dir / "m.npz");
    return dir / "m.npz";
  }());
  model.metadata["source"] = {{"registered", "/home/someone/work/reg/"}, {"database", "/data/db"}, {"mm_per_unit", 1}};
  model.metadata["note"] = "/home/someone/notes.txt";
  save_model(dir / "m2.npz", model);
  const std::string meta = Npz::load(dir / "m2.npz").text("metadata");
  EXPECT_EQ(meta.find("/home"), std::string::npos) << meta;
  EXPECT_EQ(meta.find("/data"), std::string::npos) << meta;
  const BodyModel back = load_model(dir / "m2.npz");
  EXPECT_EQ(back.metadata["source"]["registered"], "reg");
  EXPECT_EQ(back.metadata["source"]["database"], "db");
  EXPECT_EQ(back.metadata["source"]["mm_per_unit"], 1);
}

// ---- 3. silently wrong results ------------------------------------------------------------------

// A skeleton root → spine → (arm.L, arm.R) and a clip of it by bone name with arm.L bent 40°.
Skeleton small_skeleton() {
  Skeleton s;
  s.names = {"root", "spine", "arm.L", "arm.R"};
  s.parents = {-1, 0, 1, 1};
  s.heads.resize(4, 3);
  s.tails.resize(4, 3);
  s.heads << 0, 0, 0, 0, 100, 0, 10, 400, 0, -10, 400, 0;
  s.tails << 0, 100, 0, 0, 400, 0, 300, 400, 0, -300, 400, 0;
  return s;
}
std::string small_clip_text(const Skeleton& s) {
  Pose p = Pose::rest(s.bone_count());
  p.rotations[2] = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return format_bvh(skeleton_poses_to_bvh(s, {p, p}));
}
std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}

TEST(SilentResults, BvhJointsTheSkeletonCannotMapAreRefused) {
  const Skeleton s = small_skeleton();
  const std::string text = small_clip_text(s);
  ASSERT_NO_THROW(poses_from_bvh(parse_bvh(text, "ok.bvh"), s, "/nonexistent"));
  // Renamed: its 40° were dropped and the arm stayed at rest.
  std::string m = message_of([&] { poses_from_bvh(parse_bvh(replaced(text, "JOINT arm.L", "JOINT armX.L"), "renamed.bvh"), s, "/nonexistent"); });
  EXPECT_NE(m.find("BVH 'renamed.bvh'"), std::string::npos) << m;
  EXPECT_NE(m.find("armX.L"), std::string::npos) << m;
  EXPECT_NE(m.find("names no bone"), std::string::npos) << m;
  // Duplicate: the second arm.L overwrote the first.
  m = message_of([&] { poses_from_bvh(parse_bvh(replaced(text, "JOINT arm.R", "JOINT arm.L"), "dup.bvh"), s, "/nonexistent"); });
  EXPECT_NE(m.find("two joints are named 'arm.L'"), std::string::npos) << m;
  // Root-named: a joint given the root's name drove the whole body.
  m = message_of([&] {
    poses_from_bvh(parse_bvh(replaced(replaced(text, "ROOT root", "ROOT hips"), "JOINT arm.R", "JOINT root"), "rootnamed.bvh"), s,
                   "/nonexistent");
  });
  EXPECT_NE(m.find("joint 'root' hangs below 'spine'"), std::string::npos) << m;
  // A joint the skeleton lacks that never rotates (tpose.bvh's metatarsals) is harmless.
  Skeleton fewer = s;
  fewer.names.pop_back();
  fewer.parents.pop_back();
  fewer.heads.conservativeResize(3, 3);
  fewer.tails.conservativeResize(3, 3);
  EXPECT_NO_THROW(poses_from_bvh(parse_bvh(text, "ok.bvh"), fewer, "/nonexistent"));
}

TEST(SilentResults, RetargetRefusesAClipWithoutAJointItsMapNeeds) {
  // A skeleton holding every bone of the Poser/DAZ map, each a child of the root.
  const RetargetMap map = RetargetMap::poser_cmu();
  Skeleton sk;
  sk.names = {"root"};
  sk.parents = {-1};
  for (const auto& e : map.entries)
    for (const auto& t : e.targets)
      if (sk.find(t) < 0) {
        sk.names.push_back(t);
        sk.parents.push_back(0);
      }
  const int nb = sk.bone_count();
  sk.heads = Eigen::MatrixX3d::Zero(nb, 3);
  sk.tails = Eigen::MatrixX3d::Zero(nb, 3);
  for (int b = 0; b < nb; ++b) sk.tails(b, 1) = 10 + b;
  // A clip with a joint per map source, under the hip.
  auto clip_with = [&](const std::string& rename_from, const std::string& rename_to) {
    BvhMotion c;
    for (const auto& e : map.entries) {
      BvhJoint j;
      j.name = e.source == rename_from ? rename_to : e.source;
      j.parent = c.joints.empty() ? -1 : 0;
      j.offset = Eigen::Vector3d(0, c.joints.empty() ? 0 : 10, 0);
      j.channels = {BvhChannel::kZrotation, BvhChannel::kXrotation, BvhChannel::kYrotation};
      j.first_channel = 3 * static_cast<int>(c.joints.size());
      c.joints.push_back(j);
    }
    c.frames = Eigen::MatrixXd::Zero(1, 3 * static_cast<int>(c.joints.size()));
    c.source = "clip.bvh";
    return c;
  };
  EXPECT_NO_THROW(Retargeter(clip_with("", ""), sk, map));
  const std::string m = message_of([&] { Retargeter(clip_with("lShldr", "lShoulder"), sk, map); });
  EXPECT_NE(m.find("BVH 'clip.bvh': the retarget map needs joint 'lShldr' (it drives upperarm01.L"), std::string::npos)
      << m;
  EXPECT_NE(m.find("lShoulder"), std::string::npos) << m;
  EXPECT_NE(message_of([&] { Retargeter(clip_with("lShldr", "rShldr"), sk, map); }).find("two joints are named 'rShldr'"),
            std::string::npos);
}

TEST(SilentResults, AnOpenMeshIsNotMeasured) {
  const Mesh closed = fixtures::uv_sphere(100, 24, 32);
  EXPECT_NO_THROW(measure_body(closed.V, closed.F));
  // A third of the faces removed: the volume was still printed.
  Mesh open = closed;
  open.F.conservativeResize(closed.F.rows() * 2 / 3, 3);
  const std::string m = message_of([&] { measure_body(open.V, open.F); });
  EXPECT_NE(m.find("the surface is not closed"), std::string::npos) << m;
  // One missing triangle changes the volume by far less than 1 %: still measured.
  Mesh one = closed;
  one.F.conservativeResize(closed.F.rows() - 1, 3);
  EXPECT_NO_THROW(measure_body(one.V, one.F));
}

TEST(SilentResults, NegativeEigenvaluesAreRefused) {
  fixtures::TempDir dir;
  Npz z = tiny::model_npz();
  z.put("shape_eigenvalues", Eigen::VectorXd(Eigen::Vector2d(2.0, -0.5)));
  z.save(dir / "neg.npz");
  const std::string m = message_of([&] { load_model(dir / "neg.npz"); });
  EXPECT_NE(m.find("'shape_eigenvalues' element 1 is -0.5, expected a variance ≥ 0"), std::string::npos) << m;
}

// ---- 2. stale output folders: one settings record for every resumable verb ---------------------

TEST(OutputFolders, ResumableFolderResumesOnlyUnderTheSameSettings) {
  fixtures::TempDir dir;
  const fs::path out = dir / "out";
  const auto is_output = outputs_named({"table.csv"}, {".ply"});
  const nlohmann::json a = {{"scale", 1000}, {"schedule", "fast"}}, b = {{"scale", 1}, {"schedule", "fast"}};
  {
    ResumableFolder f(out, "verb.json", a, false, is_output);
    EXPECT_FALSE(fs::exists(out));  // nothing written before open()
    EXPECT_FALSE(f.open());
  }
  write_text_file(out / "x.ply", "old");
  write_text_file(out / "notes.txt", "mine");
  {
    ResumableFolder f(out, "verb.json", a, false, is_output);
    EXPECT_TRUE(f.resumes());
    EXPECT_TRUE(f.open());
    EXPECT_TRUE(fs::exists(out / "x.ply"));
  }
  // Other settings: refused, naming what differs, and nothing touched.
  const std::string m = message_of([&] { ResumableFolder(out, "verb.json", b, false, is_output); });
  EXPECT_NE(m.find("scale was 1000, now 1"), std::string::npos) << m;
  EXPECT_NE(m.find("--force"), std::string::npos) << m;
  EXPECT_TRUE(fs::exists(out / "x.ply"));
  // --force: the earlier outputs go, other files stay, the new record is written.
  {
    ResumableFolder f(out, "verb.json", b, true, is_output);
    EXPECT_FALSE(f.open());
  }
  EXPECT_FALSE(fs::exists(out / "x.ply"));
  EXPECT_TRUE(fs::exists(out / "notes.txt"));
  EXPECT_EQ(settings_difference(out / "verb.json", b), "");
  // Outputs without a record (an older bodymodel): their settings are unknown.
  fs::remove(out / "verb.json");
  write_text_file(out / "y.ply", "old");
  EXPECT_NE(message_of([&] { ResumableFolder(out, "verb.json", b, false, is_output); }).find("no verb.json"),
            std::string::npos);
  // Unrelated files only: a fresh start.
  fs::remove(out / "y.ply");
  EXPECT_FALSE(ResumableFolder(out, "verb.json", b, false, is_output).resumes());
}

TEST(OutputFolders, StagingFoldersOfEndedRunsAreRemoved) {
  // An interrupted `character` left an empty ".<out>.partial-PID" that a rerun never removed.
  fixtures::TempDir dir;
  pid_t dead = fork();
  if (dead == 0) _exit(0);
  waitpid(dead, nullptr, 0);
  const fs::path stale = dir / (".char.partial-" + std::to_string(dead));
  const fs::path live = dir / (".char.partial-" + std::to_string(getppid()));  // a running process's
  fs::create_directories(stale / "sub");
  fs::create_directories(live);
  {
    StagedFolder out(dir / "char", false);
    EXPECT_FALSE(fs::exists(stale));
    EXPECT_TRUE(fs::exists(live));
    write_text_file(out / "a.txt", "a");
    out.commit();
  }
  EXPECT_TRUE(fs::exists(dir / "char" / "a.txt"));
}

}  // namespace
}  // namespace bodymodel
