// A small model built in-test from MakeHuman bodies directly (no scanning): random subjects
// as in `bodymodel synth-db`, labels measured on the standard-pose mesh, plus a few posed
// copies of some subjects for the full model. Built once per test binary.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <random>

#include "core/makehuman.h"
#include "core/measure.h"
#include "core/skeleton.h"
#include "model/body_model.h"

namespace bodymodel::testing {

inline MacroSettings random_test_subject(std::mt19937_64& rng, bool male) {
  std::uniform_real_distribution<double> u(0, 1);
  auto in = [&](double a, double b) { return a + (b - a) * u(rng); };
  MacroSettings s;
  s.gender = male ? in(0.85, 1.0) : in(0.0, 0.15);
  s.age = in(0.45, 0.85);
  s.muscle = in(0.15, 0.85);
  s.weight = in(0.15, 0.85);
  s.height = in(0.15, 0.85);
  s.proportions = in(0.25, 0.75);
  return s;
}

inline const MakeHuman& test_makehuman() {
  static MakeHuman mh = MakeHuman::load();
  return mh;
}

struct TestSubject {
  MacroSettings sliders;
  Eigen::MatrixX3d V;  // standard pose
  BodyMeasurements m;
  bool male = false;
};

inline std::vector<TestSubject> make_test_subjects(int count, unsigned seed) {
  const MakeHuman& mh = test_makehuman();
  std::mt19937_64 rng(seed);
  std::vector<TestSubject> out;
  for (int i = 0; i < count; ++i) {
    TestSubject s;
    s.male = i % 2 == 1;
    s.sliders = random_test_subject(rng, s.male);
    s.V = mh.body(s.sliders).mesh.V;
    s.m = measure_body(s.V, mh.body_faces(), s.male ? Sex::male : Sex::female);
    out.push_back(std::move(s));
  }
  return out;
}

inline ModelBuildInput make_build_input(const std::vector<TestSubject>& subjects) {
  const MakeHuman& mh = test_makehuman();
  ModelBuildInput in;
  in.F = mh.body_faces();
  in.subject_labels = {{"sex", ""}, {"age_years", "years"}, {"height_cm", "cm"}, {"weight_kg", "kg"},
                       {"waist_cm", "cm"}, {"muscle", "%"}};
  const int n = static_cast<int>(subjects.size());
  in.subject_label_values.resize(n, in.subject_labels.size());
  in.pose_label_values.resize(n, 0);
  for (int i = 0; i < n; ++i) {
    const TestSubject& s = subjects[i];
    in.meshes.push_back(s.V);
    in.scan_ids.push_back("t" + std::to_string(i) + "_p0");
    in.subject_ids.push_back("t" + std::to_string(i));
    in.is_standard_pose.push_back(1);
    in.subject_label_values.row(i) << (s.male ? 1.0 : 0.0), s.sliders.age_years(), s.m.height_cm,
        s.m.weight_kg, s.m.waist_cm, 100 * s.sliders.muscle;
  }
  return in;
}

// 30 subjects, standard pose only.
inline std::shared_ptr<const BodyModel> shape_test_model() {
  static std::shared_ptr<const BodyModel> model = [] {
    auto subjects = make_test_subjects(30, 11);
    return std::make_shared<const BodyModel>(build_body_model(make_build_input(subjects)));
  }();
  return model;
}

}  // namespace bodymodel::testing
