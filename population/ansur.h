// ANSUR II (US Army anthropometric survey, 2012; public domain): 93 measurements of each soldier,
// as the survey's files give them — lengths in millimetres, `weightkg` in tenths of a kilogram,
// `Age` in years, `Gender` Male/Female. The reader converts weight to kilograms and refuses a file
// whose units or values are not the survey's, naming the row and column.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

namespace bodymodel {

struct AnsurTable {
  std::filesystem::path source;
  std::vector<std::string> ids;      // subjectid (SubjectId in the women's file)
  std::vector<std::string> columns;  // numeric columns, as the file names them ("weightkg" in kg)
  Eigen::MatrixXd values;            // rows × columns
  std::vector<int> male;             // 1 male, 0 female, per row
  int column(const std::string& name) const;  // InputError naming the file and the known columns
};

// Reads an ANSUR II file (ansur2_male.csv / ansur2_female.csv). Every column of `required` must be
// present and a number on every row; InputError "'<file>' line N, column 'c': …" otherwise. A
// `weightkg` column whose values all read as kilograms (none above 300) is refused: the survey
// writes tenths of a kilogram. Values out of human range (stature 1 000–2 500 mm, weight 25–300 kg,
// a length or girth 1–3 000 mm, age 15–90 years) are refused.
AnsurTable read_ansur(const std::filesystem::path& path, const std::vector<std::string>& required = {});

// Whether the file's first field is ANSUR II's subject column (`subjectid` in the men's file,
// `SubjectId` in the women's); false for an unreadable or empty file.
bool is_ansur_file(const std::filesystem::path& path);

}  // namespace bodymodel
