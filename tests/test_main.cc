#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace bodymodel::fixtures {

std::string bodymodel_exe() {
  if (const char* env = std::getenv("BODYMODEL_EXE"); env && *env) return env;
  // Test binaries live in <build>/tests/, the tool in <build>/.
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return "bodymodel";
  return (self.parent_path().parent_path() / "bodymodel").string();
}

}  // namespace bodymodel::fixtures

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
