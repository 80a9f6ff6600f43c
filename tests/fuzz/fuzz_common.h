// Shared by the libFuzzer targets: a reader may reject input only with InputError (or
// NumericalError); any other exception, crash, hang or sanitizer report is a bug.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "core/error.h"

#define BODYMODEL_FUZZ_TARGET(body)                                            \
  extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {    \
    const std::string input(reinterpret_cast<const char*>(data), size);        \
    try {                                                                      \
      body;                                                                    \
    } catch (const bodymodel::InputError&) {                                   \
    } catch (const bodymodel::NumericalError&) {                               \
    }                                                                          \
    return 0;                                                                  \
  }
