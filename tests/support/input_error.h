// The message of the InputError a call throws, for tests that check what a user is told.
#pragma once

#include <exception>
#include <functional>
#include <string>

#include "core/error.h"

namespace bodymodel::testing {

// "" when `f` throws nothing; another exception type yields "wrong exception type: ..." (so an
// expectation on the text fails, naming it).
inline std::string input_error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("wrong exception type: ") + e.what();
  }
  return "";
}

}  // namespace bodymodel::testing
