// Label values and morph targets that no body has (issue 40): a labels table with inf, NaN or
// 1e308 is refused where it is read, naming the file, line and column; a regression that would
// store non-finite coefficients names its label; a morphed body that cannot be measured names
// the targets that asked for it.
#include <gtest/gtest.h>

#include <fstream>

#include "core/error.h"
#include "support/input_error.h"
#include "core/io/mesh_io.h"
#include "fuzz/tiny_files.h"
#include "model/database.h"
#include "model/model_file.h"
#include "model/morph.h"
#include "model/semantic.h"
#include "support/fixtures.h"

namespace bodymodel {
namespace {

namespace fs = std::filesystem;

inline std::string message_of(const std::function<void()>& f) { return testing::input_error_of(f); }

TEST(LabelRanges, SubjectTablesRefuseNonFiniteAndHugeValues) {
  fixtures::TempDir dir;
  const fs::path csv = dir / "subjects.csv";
  auto with = [&](const std::string& cell, const std::string& column = "height_cm") {
    std::ofstream(csv) << "subject_id,sex," << column << "\ns0,female,170\ns1,male," << cell << "\n";
    return message_of([&] { read_subject_table(csv); });
  };
  EXPECT_EQ(with("180"), "");
  EXPECT_EQ(with(""), "");  // unknown
  for (const char* bad : {"inf", "-inf", "nan"}) {
    const std::string m = with(bad);
    EXPECT_NE(m.find("subjects.csv' line 3, column 'height_cm': '" + std::string(bad) + "' is not a finite number"),
              std::string::npos)
        << m;
  }
  EXPECT_NE(with("1e308").find("line 3, column 'height_cm': 1e308 is outside the range"), std::string::npos);
  EXPECT_NE(with("-20").find("line 3, column 'height_cm': -20 is negative"), std::string::npos);
  EXPECT_EQ(with("-20", "shape_score"), "");  // a label without a unit may be negative
}

TEST(LabelRanges, RegisteredFolderTablesNameTheRowAndColumn) {
  fixtures::TempDir dir;
  fs::create_directories(dir / "reg");
  const Mesh s = fixtures::uv_sphere(450, 8, 12);
  write_mesh(dir / "reg" / "a.ply", s);
  write_mesh(dir / "reg" / "b.ply", s);
  std::ofstream(dir / "faust.csv") << "mesh,subject,pose,weight_kg\na,s0,p0,70\nb,s1,p0,inf\n";
  const std::string m = message_of([&] { read_registered_folder(dir / "reg", dir / "faust.csv"); });
  EXPECT_NE(m.find("faust.csv' line 3, column 'weight_kg': 'inf' is not a finite number"), std::string::npos) << m;
}

TEST(LabelRanges, RegressionOfHugeLabelsNamesTheLabel) {
  const int N = 6, K = 2;
  Eigen::MatrixXd C(N, K);
  C << 1, 0, 0, 1, -1, 0, 0, -1, 0.5, 0.5, -0.5, 0.2;
  Eigen::MatrixXd Y(N, 2);
  Y.col(0) << 160, 170, 180, 175, 165, 172;
  Y.col(1) << 1e308, -1e308, 1e308, 1e308, -1e308, 1e308;
  std::vector<LabelInfo> labels = {{"height_cm", "cm"}, {"huge", ""}};
  const std::string m = message_of([&] { fit_semantic_regression(C, Y, labels); });
  EXPECT_NE(m.find("label 'huge'"), std::string::npos) << m;
  EXPECT_NO_THROW(fit_semantic_regression(C, Y.leftCols(1), {labels[0]}));
}

TEST(LabelRanges, AnUnmeasurableMorphedBodyNamesItsTargets) {
  fixtures::TempDir dir;
  tiny::model_npz().save(dir / "m.npz");
  const ShapeMorpher morpher(std::make_shared<const BodyModel>(load_model(dir / "m.npz")));
  // The tetrahedron mirrored: its faces point inward, as a body turned inside out by targets
  // that contradict each other.
  Eigen::MatrixX3d V = 1000 * tiny::tetra_vertices();
  V.col(0) *= -1;
  const std::vector<LabelCondition> targets = {LabelCondition::exact("height_cm", 150),
                                               LabelCondition::range("waist_cm", 60, 70),
                                               LabelCondition::keep_current("weight_kg")};
  const std::string m = message_of([&] { measure_morphed(morpher, V, Sex::female, targets); });
  EXPECT_NE(m.find("the targets height_cm = 150, waist_cm 60 … 70, weight_kg kept ask for a body"),
            std::string::npos)
      << m;
  EXPECT_NE(m.find("encloses no positive volume"), std::string::npos) << m;
}

}  // namespace
}  // namespace bodymodel
