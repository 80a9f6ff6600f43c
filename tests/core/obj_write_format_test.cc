// The OBJ writer (core/io/mesh_io.cc) writes with std::to_chars; its bytes must be exactly what
// the snprintf("%.9g") writer it replaced wrote, for every kind of coordinate.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <random>

#include "core/io/atomic_write.h"
#include "core/io/mesh_io.h"

namespace bodymodel {
namespace {

TEST(ObjWriter, BytesEqualPrintfPercentNineG) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  std::uniform_int_distribution<int> e(-320, 308);
  const int n = 3000;
  Eigen::MatrixX3d V(n, 3);
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) V(i, k) = u(rng) * std::pow(10.0, i < 100 ? e(rng) : (i % 7) - 2);
  // Round numbers, signed zero, extremes, subnormals and values at %.9g's rounding boundary
  // (NaN and infinity are refused by write_mesh).
  const double special[] = {0.0, -0.0, 1.0, -1.0, 100.0, 1e9, 123456789.5, 999999999.5, 0.5e-4, 1e-5,
                            std::numeric_limits<double>::max(), std::numeric_limits<double>::min(),
                            std::numeric_limits<double>::denorm_min(), -1234.56789012, 1.0000000005};
  for (size_t s = 0; s < sizeof special / sizeof special[0]; ++s) V(s / 3, s % 3) = special[s];
  Eigen::MatrixX3i F(n, 3);
  for (int f = 0; f < n; ++f) F.row(f) << f, (f * 7 + 1) % n, (f * 13 + 2) % n;
  F(0, 0) = 0;
  F(1, 0) = n - 1;

  std::string expected;
  char tmp[128];
  for (int i = 0; i < n; ++i)
    expected.append(tmp, std::snprintf(tmp, sizeof tmp, "v %.9g %.9g %.9g\n", V(i, 0), V(i, 1), V(i, 2)));
  for (int f = 0; f < n; ++f)
    expected.append(tmp, std::snprintf(tmp, sizeof tmp, "f %d %d %d\n", F(f, 0) + 1, F(f, 1) + 1, F(f, 2) + 1));

  auto path = std::filesystem::temp_directory_path() / ("bodymodel_obj_format_" + std::to_string(getpid()) + ".obj");
  write_mesh(path, V, F);
  const std::string written = read_text_file(path);
  std::filesystem::remove(path);
  ASSERT_EQ(written.size(), expected.size());
  EXPECT_TRUE(written == expected) << "first difference at byte "
                                   << std::mismatch(written.begin(), written.end(), expected.begin()).first -
                                          written.begin();
}

}  // namespace
}  // namespace bodymodel
