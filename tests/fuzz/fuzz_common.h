// Shared by the libFuzzer targets: a reader may reject input only with InputError (or
// NumericalError); any other exception, crash, hang or sanitizer report is a bug.
// The readers are in readers.h (shared with the regression test), compiled once in
// readers_lib.cc, so each target is a small translation unit.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>

#include "core/error.h"

namespace bodymodel::fuzz {
// The reader of fuzz target fuzz_<target> (readers.h readers()).
const std::function<void(const std::string&)>& reader(const std::string& target);
}  // namespace bodymodel::fuzz

#define BODYMODEL_FUZZ_TARGET(target)                                           \
  extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {     \
    static const auto& read = bodymodel::fuzz::reader(#target);                 \
    const std::string input(reinterpret_cast<const char*>(data), size);         \
    try {                                                                       \
      read(input);                                                              \
    } catch (const bodymodel::InputError&) {                                    \
    } catch (const bodymodel::NumericalError&) {                                \
    }                                                                           \
    return 0;                                                                   \
  }
