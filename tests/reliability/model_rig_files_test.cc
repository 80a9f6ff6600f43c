// Model files (model/model_file.h) and skinning rigs (skinning/rig_io.h) with one array made
// inconsistent at a time: out-of-range or cyclic parent indices, face indices past the vertex
// count, shapes that disagree, NaN, non-integer counts. Each is an InputError that names the
// file and the array; nothing reaches a solver or a kinematic chain.
#include <gtest/gtest.h>

#include <functional>
#include <limits>

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"
#include "fuzz/tiny_files.h"
#include "reliability/cli_helpers.h"
#include "support/fixtures.h"

namespace bodymodel {
namespace {

using namespace reliability;

struct Corruption {
  std::string name;                 // what the case does
  std::function<void(Npz&)> apply;  // changes one array
  std::vector<std::string> expect;  // substrings of the message (besides the file name)
};

const double kNaN = std::numeric_limits<double>::quiet_NaN();

Eigen::VectorXi ints(std::initializer_list<int> v) {
  Eigen::VectorXi x(static_cast<Eigen::Index>(v.size()));
  int i = 0;
  for (int e : v) x(i++) = e;
  return x;
}

// Sets one element of a stored float array.
std::function<void(Npz&)> set_element(const std::string& key, int r, int c, double value) {
  return [=](Npz& z) {
    Eigen::MatrixXd M = z.matrix(key);
    M(r, c) = value;
    z.put(key, M);
  };
}

TEST(ModelFileValidation, EveryInconsistentArrayIsNamed) {
  fixtures::TempDir dir;
  const fs::path file = dir / "tiny.npz";
  tiny::model_npz().save(file);
  ASSERT_NO_THROW(load_model(file));  // the control loads
  const std::vector<Corruption> cases = {
      {"face index past the vertices",
       [](Npz& z) {
         Eigen::MatrixXi F = z.int_matrix("template_faces");
         F(2, 1) = 4;
         z.put("template_faces", F);
       },
       {"'template_faces' row 2 names vertex 4", "expected 0..3"}},
      {"negative face index",
       [](Npz& z) {
         Eigen::MatrixXi F = z.int_matrix("template_faces");
         F(0, 0) = -1;
         z.put("template_faces", F);
       },
       {"'template_faces' row 0 names vertex -1"}},
      {"NaN face index", set_element("template_faces", 1, 1, kNaN), {"'template_faces'", "int32"}},
      {"NaN template vertex", set_element("template_vertices", 3, 2, kNaN),
       {"'template_vertices' holds NaN at row 3, column 2"}},
      {"NaN encoding mean", set_element("encoding_mean", 7, 0, kNaN), {"'encoding_mean' holds NaN at element 7"}},
      {"infinite basis", set_element("shape_basis", 5, 1, std::numeric_limits<double>::infinity()),
       {"'shape_basis' holds infinity"}},
      {"NaN full-model gradient", set_element("full_label_gradients", 0, 1, kNaN), {"'full_label_gradients'"}},
      {"NaN label statistics", set_element("label_statistics", 1, 2, kNaN), {"'label_statistics'"}},
      {"semantic variances of the wrong length",
       [](Npz& z) { z.put("shape_semantic_variances", Eigen::VectorXd(Eigen::VectorXd::Ones(3))); },
       {"shape_semantic_variances has 3 values, expected 2"}},
      {"bases that disagree", [](Npz& z) { z.put("shape_eigenvalues", Eigen::VectorXd(Eigen::VectorXd::Ones(5))); },
       {"shape model's arrays disagree"}},
      {"a bone its own parent", [](Npz& z) { z.put("rig_parents", ints({-1, 1})); },
       {"'rig_parents' gives bone 1 ('child') the parent 1", "below 1"}},
      {"a root with a parent (cycle)", [](Npz& z) { z.put("rig_parents", ints({1, 0})); },
       {"'rig_parents' gives bone 0 ('root') the parent 1"}},
      {"a parent past the bone count", [](Npz& z) { z.put("rig_parents", ints({-1, 7})); },
       {"'rig_parents' gives bone 1 ('child') the parent 7"}},
      {"a parent below -1", [](Npz& z) { z.put("rig_parents", ints({-2, 0})); }, {"the parent -2"}},
      {"parents of the wrong length", [](Npz& z) { z.put("rig_parents", ints({-1})); },
       {"'rig_parents' has 1 entries, 'rig_bone_names' 2 bones"}},
      {"NaN parent", [](Npz& z) { z.put("rig_parents", Eigen::VectorXd(Eigen::Vector2d(-1, kNaN))); }, {"'rig_parents'", "int32"}},
      {"regressor shape", [](Npz& z) { z.put("rig_head_regressor_shape", ints({2, 5})); },
       {"'rig_head_regressor_shape' is 2×5, expected 2×4"}},
      {"huge regressor shape", [](Npz& z) { z.put("rig_tail_regressor_shape", ints({2000000000, 4})); },
       {"'rig_tail_regressor_shape'"}},
      {"weights triplet outside", set_element("rig_weights", 0, 1, 9), {"'rig_weights' triplet 0", "outside the 4×2"}},
      {"NaN weight", set_element("rig_weights", 2, 2, kNaN), {"'rig_weights' holds NaN"}},
      {"NaN triplet row", set_element("rig_head_regressor", 1, 0, kNaN), {"'rig_head_regressor' holds NaN"}},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    Npz z = tiny::model_npz();
    c.apply(z);
    z.save(file);
    const std::string got = message_of([&] { load_model(file); });
    ASSERT_FALSE(got.empty()) << "accepted";
    EXPECT_NE(got.find("tiny.npz"), std::string::npos) << got;
    for (const auto& e : c.expect) EXPECT_NE(got.find(e), std::string::npos) << got << "\nlacks: " << e;
  }
}

TEST(RigFileValidation, EveryInconsistentArrayIsNamed) {
  fixtures::TempDir dir;
  const fs::path good = dir / "good.npz", bad = dir / "bad_rig.npz";
  tiny::write_rig(good, true);
  {
    Eigen::MatrixX3i F;
    std::vector<BoneTransforms> poses;
    Skeleton s;
    ASSERT_NO_THROW(load_rig(good, &F, &poses, &s));  // the control loads, skeleton included
    EXPECT_EQ(s.bone_count(), 2);
    EXPECT_EQ(poses.size(), 1u);
  }
  const std::vector<Corruption> cases = {
      {"face index past the vertices",
       [](Npz& z) {
         Eigen::MatrixXi F = z.int_matrix("faces");
         F(3, 2) = 4;
         z.put("faces", F);
       },
       {"'faces' row 3 names vertex 4", "expected 0..3"}},
      {"negative face index", set_element("faces", 0, 0, -3), {"'faces' row 0 names vertex -3"}},
      {"NaN bone count", [](Npz& z) { z.put("bone_count", kNaN); }, {"'bone_count'"}},
      {"fractional bone count", [](Npz& z) { z.put("bone_count", 2.5); }, {"'bone_count' is 2.5"}},
      {"huge bone count", [](Npz& z) { z.put("bone_count", 1e300); }, {"'bone_count'"}},
      {"unknown method", [](Npz& z) { z.put_text("method", "spline"); }, {"'method'", "spline"}},
      {"NaN influence", set_element("influences", 1, 0, kNaN), {"'influences'", "int32"}},
      {"influence past the bones", set_element("influences", 2, 1, 2), {"vertex 2 slot 1 names bone 2"}},
      {"coefficients of the wrong shape", [](Npz& z) { z.put("coefficients", Eigen::MatrixXd(Eigen::MatrixXd::Ones(4, 3))); },
       {"coefficients are 4 by 3"}},
      {"NaN rest position", set_element("rest", 0, 1, kNaN), {"rest positions contain NaN"}},
      {"NaN pose transform", set_element("pose_transforms", 1, 5, kNaN),
       {"'pose_transforms' row 1 (pose 0, bone 1) holds NaN"}},
      {"pose transforms of the wrong shape",
       [](Npz& z) { z.put("pose_transforms", Eigen::MatrixXd(Eigen::MatrixXd::Zero(3, 12))); }, {"'pose_transforms' must be"}},
      {"a bone its own parent", [](Npz& z) { z.put("skeleton_parents", ints({-1, 1})); },
       {"'skeleton_parents'", "parent index 1"}},
      {"a cycle", [](Npz& z) { z.put("skeleton_parents", ints({1, 0})); }, {"'skeleton_parents'", "'root'"}},
      {"a parent past the bone count", [](Npz& z) { z.put("skeleton_parents", ints({-1, 9})); },
       {"'skeleton_parents'", "parent index 9"}},
      {"parents of the wrong length", [](Npz& z) { z.put("skeleton_parents", ints({-1, 0, 1})); },
       {"'skeleton_parents' has 3 entries, 'skeleton_names' 2 bones"}},
      {"NaN joint", set_element("skeleton_heads", 1, 1, kNaN), {"'skeleton_heads'", "non-finite"}},
      {"skeleton of another size",
       [](Npz& z) {
         z.put_text("skeleton_names", R"(["a","b","c"])");
         z.put("skeleton_parents", ints({-1, 0, 1}));
         z.put("skeleton_heads", Eigen::MatrixXd(Eigen::MatrixXd::Zero(3, 3)));
         z.put("skeleton_tails", Eigen::MatrixXd(Eigen::MatrixXd::Ones(3, 3)));
       },
       {"the skeleton has 3 bones, the rig 2"}},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    Npz z = Npz::load(good);
    c.apply(z);
    z.save(bad);
    Eigen::MatrixX3i F;
    std::vector<BoneTransforms> poses;
    Skeleton s;
    const std::string got = message_of([&] { load_rig(bad, &F, &poses, &s); });
    ASSERT_FALSE(got.empty()) << "accepted";
    EXPECT_NE(got.find("bad_rig.npz"), std::string::npos) << got;
    for (const auto& e : c.expect) EXPECT_NE(got.find(e), std::string::npos) << got << "\nlacks: " << e;
  }
}

// The verbs that read a model or a rig pass the reader's message on: one line, exit 2, the file.
// A quantised model file (model_file.h, format 3) whose scales or codes are damaged is refused
// with one line naming the array and what is wrong; the undamaged one loads with the same basis
// to within half a step.
TEST(ModelFileValidation, CorruptQuantisedBasisIsRefused) {
  fixtures::TempDir dir;
  const BodyModel tiny_model = model_from_npz(tiny::model_npz(), "tiny");
  ModelFileOptions o;
  o.basis_bits = 8;
  const Npz good = model_to_npz(tiny_model, o);
  ASSERT_TRUE(good.has("shape_basis_codes"));
  const BodyModel back = model_from_npz(good, "q8");
  EXPECT_LE((back.shape.pca.basis - tiny_model.shape.pca.basis).cwiseAbs().maxCoeff(), 0.5 / 127 + 1e-9);
  const std::vector<Corruption> cases = {
      {"a scale ten times too large", [](Npz& z) {
         Eigen::MatrixXd S = z.matrix("shape_basis_scales");
         S(0, 0) *= 10;
         z.put_float32("shape_basis_scales", S);
       }, {"'shape_basis_codes' column 0 decodes to norm", "a corrupt scale in 'shape_basis_scales'"}},
      {"a NaN scale", set_element("shape_basis_scales", 0, 1, kNaN),
       {"'shape_basis_scales' row 0, column 1 is nan, expected a finite scale"}},
      {"a negative scale", set_element("shape_basis_scales", 0, 0, -0.01), {"expected a finite scale ≥ 0"}},
      {"scales of the wrong shape", [](Npz& z) { z.put("shape_basis_scales", Eigen::MatrixXd(Eigen::MatrixXd::Ones(3, 2))); },
       {"'shape_basis_scales' is 3×2"}},
      {"no block size", [](Npz& z) { z.put_int("shape_basis_block_rows", 0); }, {"'shape_basis_block_rows' is 0"}},
      {"a code of -128", [](Npz& z) {
         Eigen::MatrixXi C = z.int_matrix("shape_basis_codes");
         C(3, 1) = -128;
         z.put_small_int("shape_basis_codes", C, 1);
       }, {"holds codes outside ±127"}},
      {"codes as int32", [](Npz& z) { z.put("shape_basis_codes", Eigen::MatrixXi(z.int_matrix("shape_basis_codes"))); },
       {"'shape_basis_codes' is '<i4', expected int8"}},
  };
  for (const Corruption& c : cases) {
    Npz z = Npz::parse(good.serialize(), "q8.npz");
    c.apply(z);
    const fs::path file = dir / "bad_q8.npz";
    z.save(file);
    try {
      load_model(file);
      ADD_FAILURE() << c.name << ": accepted";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.find('\n'), std::string::npos) << c.name << ": " << msg;
      EXPECT_NE(msg.find("bad_q8.npz"), std::string::npos) << c.name << ": " << msg;
      for (const auto& s : c.expect) EXPECT_NE(msg.find(s), std::string::npos) << c.name << ": " << msg;
    }
  }
}

// A bit-packed model file (format 4: columns of other widths than 8 and 16 bits) that is truncated,
// padded, of the wrong type, or holds a code its width cannot hold, is refused with one line naming
// the file and the array; the intact one decodes to within half a step of each column.
TEST(ModelFileValidation, CorruptPackedBasisIsRefused) {
  fixtures::TempDir dir;
  const BodyModel tiny_model = model_from_npz(tiny::model_npz(), "tiny");
  ModelFileOptions o;
  o.basis_bits = 8;
  const Eigen::Index K = tiny_model.shape.component_count();
  o.shape_column_bits = Eigen::VectorXi::Constant(K, 3);
  o.shape_column_bits(0) = 5;
  o.full_column_bits = Eigen::VectorXi::Constant(tiny_model.full.component_count(), 2);
  const Npz good = model_to_npz(tiny_model, o);
  ASSERT_TRUE(good.has("shape_basis_packed"));
  EXPECT_EQ(good.scalar("format_version"), 4);
  const BodyModel back = model_from_npz(Npz::parse(good.serialize(), "q.npz"), "q.npz");
  const Eigen::MatrixXd scales = good.matrix("shape_basis_scales");
  for (Eigen::Index k = 0; k < K; ++k)
    EXPECT_LE((back.shape.pca.basis - tiny_model.shape.pca.basis).col(k).cwiseAbs().maxCoeff(),
              0.5 * scales.col(k).maxCoeff() * (1 + 1e-9) + 1e-15);
  auto bytes = [](const Npz& z) {
    const auto& v = z.arrays().at("shape_basis_packed").i64;
    return std::vector<uint8_t>(v.begin(), v.end());
  };
  const std::vector<Corruption> cases = {
      {"one byte short", [&](Npz& z) { auto b = bytes(z); b.pop_back(); z.put_bytes("shape_basis_packed", b); },
       {"'shape_basis_packed' has", "bytes, expected", "truncated or inconsistent"}},
      {"one byte too many", [&](Npz& z) { auto b = bytes(z); b.push_back(0); z.put_bytes("shape_basis_packed", b); },
       {"'shape_basis_packed' has", "truncated or inconsistent"}},
      {"a width the bytes were not packed with", [](Npz& z) {
         Eigen::VectorXi bits = z.int_vector("shape_basis_column_bits");
         bits(0) = 6;
         z.put("shape_basis_column_bits", bits);
       }, {"'shape_basis_packed' has"}},
      {"a 17-bit column", [](Npz& z) {
         Eigen::VectorXi bits = z.int_vector("shape_basis_column_bits");
         bits(1) = 17;
         z.put("shape_basis_column_bits", bits);
       }, {"column 1 of 'shape_basis_packed' has 17 bits, expected 2 to 16"}},
      {"all bits set (code 7 in a 3-bit column)", [&](Npz& z) {
         auto b = bytes(z);
         std::fill(b.begin(), b.end(), 0xFF);
         z.put_bytes("shape_basis_packed", b);
       }, {"'shape_basis_packed' holds codes outside ±"}},
      {"packed as int8", [&](Npz& z) {
         auto b = bytes(z);
         Eigen::MatrixXi m(static_cast<Eigen::Index>(b.size()), 1);
         for (size_t i = 0; i < b.size(); ++i) m(static_cast<Eigen::Index>(i), 0) = b[i] > 127 ? 0 : b[i];
         z.put_small_int("shape_basis_packed", m, 1);
       }, {"'shape_basis_packed' is '|i1', expected uint8"}},
  };
  for (const Corruption& c : cases) {
    Npz z = Npz::parse(good.serialize(), "q.npz");
    c.apply(z);
    const fs::path file = dir / "bad_packed.npz";
    z.save(file);
    try {
      load_model(file);
      ADD_FAILURE() << c.name << ": accepted";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.find('\n'), std::string::npos) << c.name << ": " << msg;
      EXPECT_NE(msg.find("bad_packed.npz"), std::string::npos) << c.name << ": " << msg;
      for (const auto& s : c.expect) EXPECT_NE(msg.find(s), std::string::npos) << c.name << ": " << msg;
    }
  }
}

TEST(ModelFileValidation, VerbsNameTheBadFile) {
  fixtures::TempDir dir;
  Npz z = tiny::model_npz();
  z.put("rig_parents", ints({1, 0}));
  z.save(dir / "cyclic_model.npz");
  tiny::write_rig(dir / "rig.npz", true);
  Npz r = Npz::load(dir / "rig.npz");
  r.put("skeleton_parents", ints({1, 0}));
  r.save(dir / "cyclic_rig.npz");
  write_mesh(dir / "body.obj", tiny::tetra_vertices(), tiny::tetra_faces());
  write_text_file(dir / "clip.bvh", "HIERARCHY\nROOT root\n{\nOFFSET 0 0 0\nCHANNELS 3 Zrotation Xrotation "
                                    "Yrotation\nEnd Site\n{\nOFFSET 0 1 0\n}\n}\nMOTION\nFrames: 1\n"
                                    "Frame Time: 0.1\n0 0 0\n");
  const std::string model = (dir / "cyclic_model.npz").string(), rig = (dir / "cyclic_rig.npz").string(),
                    body = (dir / "body.obj").string(), bvh = (dir / "clip.bvh").string();
  const std::vector<std::vector<std::string>> runs = {
      {"generate", model, "--out", (dir / "g").string()},
      {"morph", model, "--in", body, "--set", "height_cm=170", "--out", (dir / "m.obj").string()},
      {"pose", model, "--in", body, "--bvh", bvh, "--out", (dir / "p.obj").string()},
      {"edit", model, "--in", body, "--handle", "0:1,0,0", "--out", (dir / "e.obj").string()},
      {"character", model, "--out", (dir / "c").string()},
      {"crowd", model, "--bvh", bvh, "--out", (dir / "crowd").string()},
      {"skin", "apply", rig, "--bvh", bvh, "--out", (dir / "frames").string()},
      {"skin", "export-gltf", "--rig", rig, "--out", (dir / "x.glb").string()},
      {"animate", rig, "--bvh", bvh, "--out", (dir / "anim").string()},
  };
  for (const auto& args : runs) {
    SCOPED_TRACE(args[0] + " " + args[1]);
    std::string out;
    EXPECT_EQ(run_bodymodel(args, dir / "log.txt", &out), 2) << out;
    const auto lines = error_lines(out);
    ASSERT_EQ(lines.size(), 1u) << out;
    const bool names_file = lines[0].find("cyclic_model.npz") != std::string::npos ||
                            lines[0].find("cyclic_rig.npz") != std::string::npos;
    EXPECT_TRUE(names_file) << lines[0];
    EXPECT_NE(lines[0].find("parent"), std::string::npos) << lines[0];
  }
}

}  // namespace
}  // namespace bodymodel
