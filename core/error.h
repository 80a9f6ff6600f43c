// Errors. Bad input throws InputError with a message that names the file (or element), what
// was expected and what was found; the command line prints it as one line and exits non-zero.
#pragma once

#include <stdexcept>
#include <string>

namespace bodymodel {

// Bad input data or arguments supplied by the user (a file, a value, a mesh that does not fit).
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A numerical failure (factorisation failed, solver did not converge, NaN produced).
class NumericalError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace bodymodel
