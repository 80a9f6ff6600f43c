#include "core/random_subject.h"

namespace bodymodel {

MacroSettings random_makehuman_subject(std::mt19937_64& rng, bool male) {
  std::uniform_real_distribution<double> u(0, 1);
  auto in = [&](double a, double b) { return a + (b - a) * u(rng); };
  MacroSettings s;
  s.gender = male ? in(0.85, 1.0) : in(0.0, 0.15);
  s.age = in(0.45, 0.85);          // about 23 to 70 years
  s.muscle = in(0.15, 0.85);
  s.weight = in(0.15, 0.85);
  s.height = in(0.15, 0.85);
  s.proportions = in(0.25, 0.75);
  s.cup = in(0.3, 0.7);
  s.firmness = in(0.3, 0.7);
  std::gamma_distribution<double> g(2.0, 1.0);
  double a = g(rng), b = g(rng), c = g(rng), sum = a + b + c;
  s.african = a / sum;
  s.asian = b / sum;
  s.caucasian = c / sum;
  return s;
}

}  // namespace bodymodel
