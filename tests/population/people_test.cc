// People files and population sampling (population/people.h).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>

#include "core/data_path.h"
#include "core/error.h"
#include "population/people.h"
#include "support/fixtures.h"

using namespace bodymodel;
namespace fs = std::filesystem;

namespace {

fs::path write_file(const fixtures::TempDir& dir, const std::string& name, const std::string& text) {
  const fs::path p = dir.path / name;
  std::ofstream(p) << text;
  return p;
}

const PeopleTable& nhanes() {
  static const PeopleTable t = read_people(data_file("anthropometry") / "nhanes_2017_2020_bmx_demo.csv");
  return t;
}

}  // namespace

TEST(People, ReadsNhanesAndOwnColumnNames) {
  fixtures::TempDir dir;
  const fs::path a = write_file(dir, "a.csv",
                                "# comment\n\"SEQN\",\"RIAGENDR\",\"RIDAGEYR\",\"BMXHT\",\"BMXWT\",\"BMXWAIST\",\"OTHER\"\n"
                                "7,2,40,160.5,70,NA,x\n8,1,17,180,80,90,y\n");
  const PeopleTable t = read_people(a);
  ASSERT_EQ(t.people.size(), 2u);
  EXPECT_EQ(t.people[0].id, "7");
  EXPECT_EQ(t.people[0].sex, Sex::female);
  EXPECT_EQ(t.people[0].line, 3);
  EXPECT_DOUBLE_EQ(t.people[0].measurement("height_cm"), 160.5);
  EXPECT_TRUE(std::isnan(t.people[0].measurement("waist_iliac_cm")));
  EXPECT_EQ(t.people[1].sex, Sex::male);
  const fs::path b = write_file(dir, "b.csv", "sex,age_years,height_cm,weight_kg\nfemale,30,165,60\n");
  const PeopleTable u = read_people(b);
  EXPECT_EQ(u.people[0].id, "1");  // the row number without an id column
  EXPECT_TRUE(u.has("height_cm"));
  // Strict selection: the 17-year-old and the missing waist are errors naming the line...
  EXPECT_THROW(select_people(t, {"height_cm"}, false, false), InputError);
  try {
    select_people(t, {"height_cm", "waist_iliac_cm"}, false, false);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("line 3"), std::string::npos) << e.what();
  }
  // ... or skipped and counted.
  const PeopleSelection s = select_people(t, {"height_cm"}, false, true);
  EXPECT_EQ(s.rows, std::vector<int>{0});
  EXPECT_EQ(s.children, 1);
  EXPECT_EQ(select_people(t, {"height_cm"}, true, false).rows.size(), 2u);
}

TEST(People, BadFilesAreOneClearError) {
  fixtures::TempDir dir;
  auto message = [&](const std::string& text, const std::vector<std::string>& need) {
    try {
      const PeopleTable t = read_people(write_file(dir, "x.csv", text));
      require_columns(t, need);
      select_people(t, need, false, false);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("SEQN,RIAGENDR,RIDAGEYR\n1,2,40\n", {"sex", "height_cm"}).find("BMXHT"), std::string::npos);
  EXPECT_NE(message("SEQN,RIAGENDR,RIDAGEYR,BMXHT\n1,2,40,abc\n", {"height_cm"}).find("not a number"), std::string::npos);
  EXPECT_NE(message("SEQN,RIAGENDR,RIDAGEYR,BMXHT\n1,3,40,150\n", {"height_cm"}).find("sex"), std::string::npos);
  EXPECT_NE(message("SEQN,RIAGENDR,RIDAGEYR,BMXHT\nNA,NA,NA,NA\nNA,NA,NA,NA\n", {"height_cm"}).find("line 2"),
            std::string::npos);
  EXPECT_NE(message("SEQN,RIAGENDR\n", {"sex"}).find("no data"), std::string::npos);
}

TEST(People, SamplingIsReproducibleBySeedAndFollowsTheSurveyWeights) {
  const PeopleTable& t = nhanes();
  PopulationFilter f;
  const EligibleSummary e = eligible_people(t, f);
  ASSERT_GT(e.eligible.size(), 5000u);
  EXPECT_GT(e.children, 3000);
  const auto a = sample_population(t, e.eligible, 400, 11), b = sample_population(t, e.eligible, 400, 11),
             c = sample_population(t, e.eligible, 400, 12);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  // The weighted population's height and weight per sex against the sample's: the systematic,
  // stratified draw keeps the KS distance small (independent draws of ~200 per sex give ~0.06).
  for (Sex sex : {Sex::female, Sex::male})
    for (const char* m : {"height_cm", "weight_kg"}) {
      std::vector<double> pop, w, drawn;
      for (int i : e.eligible)
        if (t.people[i].sex == sex) pop.push_back(t.people[i].measurement(m)), w.push_back(t.people[i].survey_weight);
      for (int i : a)
        if (t.people[i].sex == sex) drawn.push_back(t.people[i].measurement(m));
      EXPECT_LT(ks_statistic(drawn, pop, w), 0.05) << m;
    }
  // Unweighted, the sample would be NHANES' design (oversampled groups): the survey weight matters.
  std::vector<double> all, ones, drawn;
  for (int i : e.eligible) all.push_back(t.people[i].age_years), ones.push_back(1.0);
  for (int i : a) drawn.push_back(t.people[i].age_years);
  std::vector<double> wt;
  for (int i : e.eligible) wt.push_back(t.people[i].survey_weight);
  EXPECT_LT(ks_statistic(drawn, all, wt), ks_statistic(drawn, all, ones));
}

TEST(People, KsStatisticOfKnownSamples) {
  EXPECT_DOUBLE_EQ(ks_statistic({1, 2, 3}, {1, 2, 3}, {1, 1, 1}), 0.0);
  EXPECT_DOUBLE_EQ(ks_statistic({1, 2}, {3, 4}, {1, 1}), 1.0);
  // Weights: b puts 3/4 on 1 and 1/4 on 2; a is half-half: sup |F_a − F_b| = 0.25 at 1.
  EXPECT_DOUBLE_EQ(ks_statistic({1, 2}, {1, 2}, {3, 1}), 0.25);
}
