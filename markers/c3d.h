// C3D files (www.c3d.org, "The C3D File Format User Guide"): the POINT section. Read: the header,
// the parameter section (POINT:USED, SCALE, RATE, DATA_START, FRAMES, LABELS, LABELS2…, UNITS),
// integer (POINT:SCALE > 0) and floating-point (SCALE < 0) samples, Intel, DEC (VAX F floats) and
// MIPS (big-endian) processor types; a sample whose residual word is negative is missing. Analog
// samples are skipped. Write: the same, with a minimal parameter section (POINT group only).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "markers/marker_data.h"

namespace bodymodel {

enum class C3dProcessor { intel = 84, dec = 85, mips = 86 };

struct C3dWriteOptions {
  C3dProcessor processor = C3dProcessor::intel;
  bool floating = true;  // floating-point samples; false: 16-bit integers times `scale`
  double scale = 0;      // mm per integer step (integer storage); 0 = the smallest that fits the data
};

// Parses C3D bytes; `source` names the file in errors. Every count is checked against the bytes
// before anything is allocated from it. Coordinates are converted to mm (POINT:UNITS mm, cm, m).
MarkerData parse_c3d(const std::string& bytes, const std::string& source);
MarkerData read_c3d(const std::filesystem::path& path);

// The capture as C3D bytes. InputError when a count or coordinate does not fit the format (more
// than 32767 markers or 65535 frames; integer storage beyond ±32767 steps).
std::string c3d_bytes(const MarkerData& d, const C3dWriteOptions& options = {});
void write_c3d(const std::filesystem::path& path, const MarkerData& d, const C3dWriteOptions& options = {});

// VAX F_floating (C3D "DEC" processor) <-> value, as the four bytes stored in the file.
double dec_float_value(const unsigned char bytes[4]);
void dec_float_bytes(float value, unsigned char bytes[4]);

}  // namespace bodymodel
