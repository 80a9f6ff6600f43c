// Marker files (markers/c3d.h, markers/trc.h): files of every C3D storage variant built byte by
// byte here from the C3D User Guide (not with our writer), write -> read round trips, and hostile
// files that must end with one InputError line.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>
#include <unistd.h>
#include <string>
#include <vector>

#include "core/error.h"
#include "markers/c3d.h"
#include "markers/marker_data.h"
#include "markers/trc.h"

namespace bodymodel {
namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---- a C3D file built by hand -------------------------------------------------------------------
// Processor 84 (Intel: little-endian IEEE), 85 (DEC: little-endian 16-bit words, VAX F floats) or
// 86 (MIPS: big-endian IEEE).
struct Hand {
  int proc;
  std::string s;
  void byte(int v) { s.push_back(static_cast<char>(v & 0xFF)); }
  void word(int v) {
    if (proc == 86) byte(v >> 8), byte(v);
    else byte(v), byte(v >> 8);
  }
  void real(float v) {
    uint32_t u;
    if (proc == 85) {
      // A VAX F float is the IEEE bit pattern of 4·v with its two 16-bit halves exchanged (the
      // exponent bias is 128 against 127 and the hidden bit is worth 1/2 against 1).
      const float q = 4 * v;
      std::memcpy(&u, &q, 4);
      u = (u >> 16) | (u << 16);
    } else {
      std::memcpy(&u, &v, 4);
    }
    if (proc == 86) byte(u >> 24), byte(u >> 16), byte(u >> 8), byte(u);
    else byte(u), byte(u >> 8), byte(u >> 16), byte(u >> 24);
  }
  void pad_to(size_t n) { s.resize(n, '\0'); }
};

// Two markers ("HEAD", "LTOE") and 3 frames, 2 analog samples per frame to skip, the POINT
// group defined after its parameters and an ANALOG group; marker 2 is missing in frame 2
// (residual word -1), marker 1 in frame 3 has a camera mask (high byte) and residual 3 (valid).
std::string hand_c3d(int proc, bool floating) {
  Hand h{proc, {}};
  const float scale = floating ? -0.5f : 0.5f;
  // Header block (words of 2 bytes, 1-based numbering of the User Guide).
  h.byte(2), h.byte(0x50);     // word 1: parameters at block 2, key 0x50
  h.word(2);                   // word 2: 3-D points
  h.word(2);                   // word 3: analog samples per 3-D frame (all channels)
  h.word(10), h.word(12);      // words 4, 5: first and last frame
  h.word(0);                   // word 6: max interpolation gap
  h.real(scale);               // words 7-8: scale
  h.word(4);                   // word 9: DATA_START (block 4)
  h.word(1);                   // word 10: analog samples per frame per channel
  h.real(120.0f);              // words 11-12: frame rate
  h.pad_to(512);
  // Parameter section: blocks 2-3 (two blocks: DATA_START is 4).
  h.byte(1), h.byte(0x50), h.byte(2), h.byte(proc);
  auto param = [&](const std::string& name, int group, const std::string& body) {
    h.byte(static_cast<int>(name.size())), h.byte(group), h.s += name;
    h.word(static_cast<int>(2 + body.size() + 1)), h.s += body, h.byte(0);  // offset, body, no description
  };
  auto word_body = [&](int v) { Hand b{proc, {}}; b.byte(2), b.byte(0), b.word(v); return b.s; };
  auto real_body = [&](float v) { Hand b{proc, {}}; b.byte(4), b.byte(0), b.real(v); return b.s; };
  param("USED", 1, word_body(2));
  param("SCALE", 1, real_body(scale));
  param("RATE", 1, real_body(120.0f));
  param("DATA_START", 1, word_body(4));
  param("LABELS", 1, std::string("\xff\x02\x04\x02HEADLTOE", 12));
  param("UNITS", 1, std::string("\xff\x01\x02mm", 5));
  param("USED", 2, word_body(2));
  h.byte(5), h.byte(-1), h.s += "POINT", h.word(3), h.byte(0);    // group 1, defined last
  h.byte(6), h.byte(-2), h.s += "ANALOG", h.word(3), h.byte(0);   // group 2
  h.byte(0), h.byte(0);  // a record with an empty name ends the section
  h.pad_to(3 * 512);
  // Frames: X Y Z residual per point, then the analog samples.
  const int xyz[3][2][3] = {{{100, -200, 300}, {7, 8, 9}}, {{102, -198, 301}, {0, 0, 0}}, {{104, -196, 302}, {11, 12, 13}}};
  const int residual[3][2] = {{0, 5}, {2, -1}, {0x0303, 1}};
  for (int f = 0; f < 3; ++f) {
    for (int m = 0; m < 2; ++m) {
      for (int k = 0; k < 3; ++k) floating ? h.real(xyz[f][m][k] * 0.5f) : h.word(xyz[f][m][k]);
      floating ? h.real(float(residual[f][m])) : h.word(residual[f][m]);
    }
    for (int a = 0; a < 2; ++a) floating ? h.real(1000.0f + a) : h.word(1000 + a);
  }
  h.pad_to(5 * 512);
  return h.s;
}

void expect_hand_file(const MarkerData& d) {
  ASSERT_EQ(d.marker_count(), 2);
  EXPECT_EQ(d.labels[0], "HEAD");
  EXPECT_EQ(d.labels[1], "LTOE");
  EXPECT_EQ(d.rate, 120.0);
  EXPECT_EQ(d.first_frame, 10);
  ASSERT_EQ(d.frame_count(), 3);
  EXPECT_EQ(d.at(0, 0), Eigen::Vector3d(50, -100, 150));
  EXPECT_EQ(d.at(0, 1), Eigen::Vector3d(3.5, 4, 4.5));
  EXPECT_EQ(d.at(1, 0), Eigen::Vector3d(51, -99, 150.5));
  EXPECT_FALSE(d.present(1, 1)) << "residual word -1 marks a missing sample";
  EXPECT_TRUE(d.present(2, 0)) << "a camera mask in the residual word's high byte is a valid sample";
  EXPECT_EQ(d.at(2, 0), Eigen::Vector3d(52, -98, 151));
  EXPECT_EQ(d.at(2, 1), Eigen::Vector3d(5.5, 6, 6.5));
}

TEST(C3d, ReadsHandWrittenIntelInteger) { expect_hand_file(parse_c3d(hand_c3d(84, false), "intel-int.c3d")); }
TEST(C3d, ReadsHandWrittenIntelFloat) { expect_hand_file(parse_c3d(hand_c3d(84, true), "intel-float.c3d")); }
TEST(C3d, ReadsHandWrittenDecInteger) { expect_hand_file(parse_c3d(hand_c3d(85, false), "dec-int.c3d")); }
TEST(C3d, ReadsHandWrittenDecFloat) { expect_hand_file(parse_c3d(hand_c3d(85, true), "dec-float.c3d")); }
TEST(C3d, ReadsHandWrittenMipsIntegerAndFloat) {
  expect_hand_file(parse_c3d(hand_c3d(86, false), "mips-int.c3d"));
  expect_hand_file(parse_c3d(hand_c3d(86, true), "mips-float.c3d"));
}

TEST(C3d, DecFloatsDecodeKnownBitPatterns) {
  // VAX F: 1.0 is the word 0x4080 (exponent 129, mantissa 0.1b), then 0x0000.
  const unsigned char one[4] = {0x80, 0x40, 0, 0};
  EXPECT_EQ(dec_float_value(one), 1.0);
  const unsigned char minus_two[4] = {0x00, 0xC1, 0, 0};  // sign, exponent 130
  EXPECT_EQ(dec_float_value(minus_two), -2.0);
  const unsigned char one_and_half[4] = {0xC0, 0x40, 0, 0};  // mantissa 0.11b
  EXPECT_EQ(dec_float_value(one_and_half), 1.5);
  const unsigned char zero[4] = {0, 0, 0, 0};
  EXPECT_EQ(dec_float_value(zero), 0.0);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1e4f, 1e4f);
  for (int i = 0; i < 1000; ++i) {
    const float v = u(rng);
    unsigned char b[4];
    dec_float_bytes(v, b);
    EXPECT_EQ(dec_float_value(b), double(v));
  }
}

MarkerData random_capture(int markers, int frames, unsigned seed) {
  MarkerData d;
  for (int m = 0; m < markers; ++m) d.labels.push_back((m % 7 == 3 ? "*" : "M") + std::to_string(m));
  d.rate = 120;
  d.first_frame = 3;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-2000.f, 2000.f);
  d.xyz.resize(frames, 3 * markers);
  for (int f = 0; f < frames; ++f)
    for (int m = 0; m < markers; ++m)
      if (rng() % 5 == 0) d.clear(f, m);
      else d.set(f, m, Eigen::Vector3d(u(rng), u(rng), u(rng)));
  return d;
}

void expect_same_missing(const MarkerData& a, const MarkerData& b) {
  ASSERT_EQ(a.frame_count(), b.frame_count());
  ASSERT_EQ(a.labels, b.labels);
  for (int f = 0; f < a.frame_count(); ++f)
    for (int m = 0; m < a.marker_count(); ++m) ASSERT_EQ(a.present(f, m), b.present(f, m)) << f << " " << m;
}

TEST(C3d, WriteReadIsExactForEveryProcessorAndStorage) {
  const MarkerData d = random_capture(300, 20, 1);  // > 255 labels: POINT:LABELS2
  for (auto proc : {C3dProcessor::intel, C3dProcessor::dec, C3dProcessor::mips}) {
    const MarkerData f = parse_c3d(c3d_bytes(d, {proc, true, 0}), "float.c3d");
    expect_same_missing(d, f);
    EXPECT_EQ(f.rate, d.rate);
    EXPECT_EQ(f.first_frame, d.first_frame);
    for (int i = 0; i < d.frame_count(); ++i)
      for (int m = 0; m < d.marker_count(); ++m)
        if (d.present(i, m)) {
          ASSERT_EQ(f.at(i, m), d.at(i, m)) << "float storage is exact for float data";
        }
    const double scale = 0.125;
    const MarkerData n = parse_c3d(c3d_bytes(d, {proc, false, scale}), "int.c3d");
    expect_same_missing(d, n);
    double worst = 0;
    for (int i = 0; i < d.frame_count(); ++i)
      for (int m = 0; m < d.marker_count(); ++m)
        if (d.present(i, m)) worst = std::max(worst, (n.at(i, m) - d.at(i, m)).cwiseAbs().maxCoeff());
    EXPECT_LE(worst, scale / 2 + 1e-9) << "integer storage is within half a step";
    EXPECT_GT(worst, 0) << "the data are not all on the integer grid (the test could fail)";
  }
}

TEST(C3d, IntegerStorageRefusesCoordinatesBeyondItsRange) {
  MarkerData d = random_capture(2, 2, 2);
  d.set(0, 0, Eigen::Vector3d(5000, 0, 0));
  EXPECT_THROW(c3d_bytes(d, {C3dProcessor::intel, false, 0.1}), InputError);
  EXPECT_NO_THROW(c3d_bytes(d, {C3dProcessor::intel, false, 0}));  // the automatic scale fits
}

std::string error_of(const std::string& bytes) {
  try {
    parse_c3d(bytes, "bad.c3d");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(C3d, HostileFilesEndWithOneClearLine) {
  const std::string good = hand_c3d(84, false);
  auto with = [&](size_t at, std::initializer_list<int> bytes) {
    std::string s = good;
    for (int b : bytes) s[at++] = static_cast<char>(b);
    return s;
  };
  EXPECT_NE(error_of(good.substr(0, 300)).find("truncated"), std::string::npos);
  EXPECT_NE(error_of(good.substr(0, 3 * 512 + 20)).find("truncated"), std::string::npos);
  EXPECT_NE(error_of(with(1, {0x51})).find("not a C3D file"), std::string::npos);
  EXPECT_NE(error_of(with(515, {99})).find("processor type"), std::string::npos);
  // Frame count from the header near 65535: more frames than bytes, refused before allocating.
  EXPECT_NE(error_of(with(8, {0xFF, 0xFF})).find("truncated"), std::string::npos);
  // POINT:USED (first parameter's data, after its 4 name bytes) set to 32767 points.
  const size_t used = 512 + 4 + 2 + 4 + 2 + 2;
  EXPECT_NE(error_of(with(used, {0xFF, 0x7F})).find("truncated"), std::string::npos);
  // A parameter's data type byte changed to 3.
  EXPECT_NE(error_of(with(used - 2, {3})).find("data type 3"), std::string::npos);
  // A parameter with 8 dimensions.
  EXPECT_NE(error_of(with(used - 1, {8})).find("dimensions"), std::string::npos);
  // Every cut before the end of the last frame (block 4 + 3 frames of 20 bytes) is refused.
  for (size_t cut = 0; cut < 3 * 512 + 60; cut += 37) {
    const std::string e = error_of(good.substr(0, cut));
    EXPECT_EQ(e.find('\n'), std::string::npos);
    EXPECT_EQ(e.rfind("C3D 'bad.c3d': ", 0), 0u) << "cut at " << cut << ": " << e;
  }
}

// ---- TRC ---------------------------------------------------------------------------------------

const char* kTrc =
    "PathFileType\t4\t(X/Y/Z)\twalk.trc\r\n"
    "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\r\n"
    "60\t60\t3\t2\tm\t60\t1\t3\r\n"
    "Frame#\tTime\tRASI\t\t\t*7\t\t\r\n"
    "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\r\n"
    "\r\n"
    "5\t0.0\t0.1\t0.2\t0.3\t1\t2\t3\r\n"
    "6\t0.0167\t\t\t\t1.5\t2.5\t-3.5\r\n"
    "7\t0.0333\t0.125\t0.25\t0.5\r\n";

TEST(Trc, ReadsAHandWrittenFileWithEmptyFieldsAndMetres) {
  const MarkerData d = parse_trc(kTrc, "walk.trc");
  ASSERT_EQ(d.labels, (std::vector<std::string>{"RASI", "*7"}));
  EXPECT_EQ(d.rate, 60);
  EXPECT_EQ(d.first_frame, 5);
  ASSERT_EQ(d.frame_count(), 3);
  EXPECT_NEAR((d.at(0, 0) - Eigen::Vector3d(100, 200, 300)).norm(), 0, 1e-9) << "metres read as mm";
  EXPECT_FALSE(d.present(1, 0)) << "empty fields are a missing sample";
  EXPECT_NEAR((d.at(1, 1) - Eigen::Vector3d(1500, 2500, -3500)).norm(), 0, 1e-9);
  EXPECT_FALSE(d.present(2, 1)) << "a row that ends early: the rest is missing";
  EXPECT_NEAR((d.at(2, 0) - Eigen::Vector3d(125, 250, 500)).norm(), 0, 1e-9);
}

TEST(Trc, WriteReadIsExact) {
  const MarkerData d = random_capture(40, 30, 5);
  const MarkerData r = parse_trc(trc_text(d), "again.trc");
  expect_same_missing(d, r);
  EXPECT_EQ(r.rate, d.rate);
  EXPECT_EQ(r.first_frame, d.first_frame);
  for (int f = 0; f < d.frame_count(); ++f)
    for (int m = 0; m < d.marker_count(); ++m)
      if (d.present(f, m)) {
        ASSERT_EQ(r.at(f, m), d.at(f, m));
      }
}

TEST(Trc, BadFilesEndWithOneClearLine) {
  auto error = [](const std::string& text) {
    try {
      parse_trc(text, "bad.trc");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const std::string good = kTrc;
  auto replaced = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    s.replace(s.find(from), from.size(), to);
    return s;
  };
  EXPECT_NE(error(good.substr(0, 40)).find("truncated"), std::string::npos);
  EXPECT_NE(error(replaced("60\t60\t3\t2", "60\t60\t4\t2")).find("NumFrames is 4 but the file holds 3"), std::string::npos);
  EXPECT_NE(error(replaced("60\t60\t3\t2", "60\t60\t3\t3")).find("NumMarkers"), std::string::npos);
  EXPECT_NE(error(replaced("60\t60\t3\t2", "60\t60\t999999999\t2")).find("absurd"), std::string::npos);
  EXPECT_NE(error(replaced("\t1.5\t", "\tx1.5\t")).find("line 8: column 6"), std::string::npos);
  EXPECT_NE(error(replaced("\t1\t2\t3", "\t1\t\t3")).find("2 of its 3"), std::string::npos);
  EXPECT_NE(error(replaced("\tm\t", "\tfurlong\t")).find("unknown length unit"), std::string::npos);
  EXPECT_NE(error(replaced("0.125", "nan")).find("not a finite number"), std::string::npos);
  EXPECT_NE(error(replaced("PathFileType", "Path")).find("not a TRC file"), std::string::npos);
}

TEST(MarkerFiles, ReadAndWriteByExtension) {
  const MarkerData d = random_capture(5, 4, 9);
  const auto dir = std::filesystem::temp_directory_path() / ("bodymodel_markers_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  for (const char* name : {"a.c3d", "b.TRC"}) {
    write_markers(dir / name, d);
    expect_same_missing(d, read_markers(dir / name));
  }
  EXPECT_THROW(write_markers(dir / "c.csv", d), InputError);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bodymodel
